"""Pipelined replies: which command a RIG_FEEDBACK answers, and whether it is still young enough to use.

The bench sends one BENCH_CMD per tick whatever the replies do; a USB CAN
adapter brings each reply 1.5-3.5 ms later, so replies arrive ticks after
their command, in order. :class:`ReplyMatcher` remembers the tick of each
counter value it sent and matches a reply by its echoed counter whenever it
comes. A reply whose sample would be older than ``max_age_ticks`` at the
tick that could use it is never used; a command that stays unanswered that
long counts as missed.

Two streaks, for two different faults: ``unanswered_in_row`` counts
commands in a row that got no reply at all (the rig or the link went
silent: a test ends after a few), reset by any reply that comes, too late
or not; ``missed_in_row`` counts commands in a row without a usable reply
(the controller has run on an old sample since), reset only by a usable one.
A link that held its frames back a few milliseconds once (a USB adapter's
host controller, a busy rig) breaks only the second, briefly.

Pure bookkeeping, no bus and no clock: the loop and replay run the same
matching on the same frames, so a replay sees exactly the samples the loop
used.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field

from edc_bench.config.models import Variant

#: Ticks of the synchronising SAFE command's reply: the sample the first tick uses.
SYNC_TICK = -1


def max_reply_age_ticks(variant: Variant) -> int:
    """The oldest sample the loop may use, in ticks (``acceptance.max_reply_age_ms``; at least one tick).

    The gain check takes the same figure as the loop's worst transport delay.
    """
    return max(1, math.ceil(variant.acceptance.max_reply_age_ms * 1e-3 / variant.controller.period_s - 1e-9))


def stale_limit_ticks(variant: Variant) -> int:
    """Commands in a row without a usable reply after which a test ends: as long as the rig's watchdog lets the
    bench go silent (``rig.watchdog_ms``), and never fewer than ``acceptance.max_missed_replies_in_row``."""
    watchdog = math.ceil(variant.rig.watchdog_ms * 1e-3 / variant.controller.period_s - 1e-9)
    return max(variant.acceptance.max_missed_replies_in_row, watchdog)


@dataclass
class ReplyCounts:
    """What the matcher has seen of the replies."""

    matched: int = 0
    too_old: int = 0  # answered, but too late to be used
    unmatched: int = 0  # a counter no command in flight carries (stale, repeated, or from another host)
    missed: int = 0  # commands never answered within the age limit
    missed_in_row: int = 0  # commands in a row without a usable reply
    max_missed_in_row: int = 0
    unanswered_in_row: int = 0  # commands in a row with no reply at all yet (any reply that comes resets it)
    max_unanswered_in_row: int = 0
    ages: dict[int, int] = field(default_factory=dict)  # age in ticks at arrival -> replies


class ReplyMatcher:
    """Matches replies to commands by counter, up to a maximum age.

    Parameters
    ----------
    max_age_ticks : int
        A sample is usable up to this many ticks after its command's tick.
    """

    def __init__(self, max_age_ticks: int) -> None:
        self.max_age_ticks = max_age_ticks
        self._tick_of: list[int | None] = [None] * 256  # counter -> tick of the command in flight with it
        self._in_flight: deque[tuple[int, int]] = deque()  # (tick, counter), oldest first
        self._answered: set[int] = set()
        self._expired: set[int] = set()  # ticks whose commands expired unanswered
        self._late: set[int] = set()  # ticks whose replies came too old before their commands expired
        # expired commands with no reply at all, newer than the newest command that got one: the silence
        self._silent: deque[int] = deque()
        self._newest_replied = SYNC_TICK
        self.newest_tick = SYNC_TICK
        self.counts = ReplyCounts()

    def sent(self, tick: int, counter: int) -> list[int]:
        """A command for ``tick`` went out with ``counter``.

        Returns
        -------
        list of int
            Ticks whose commands have just become too old to be answered in time, unanswered (missed).
        """
        missed = []
        in_flight, counts = self._in_flight, self.counts
        while in_flight and tick - in_flight[0][0] > self.max_age_ticks:
            old_tick, _ = in_flight.popleft()
            if old_tick in self._answered:
                self._answered.discard(old_tick)
                counts.missed_in_row = 0
                continue
            missed.append(old_tick)
            counts.missed += 1
            counts.missed_in_row += 1
            counts.max_missed_in_row = max(counts.max_missed_in_row, counts.missed_in_row)
            if old_tick in self._late:  # answered, too late: the link is slow, not silent
                self._late.discard(old_tick)
                continue
            # its reply may still come, too late: remembered until the counter comes round again
            self._expired.add(old_tick)
            if old_tick > self._newest_replied:  # no later command answered either: the silence goes on
                self._silent.append(old_tick)
                counts.unanswered_in_row = len(self._silent)
                counts.max_unanswered_in_row = max(counts.max_unanswered_in_row, counts.unanswered_in_row)
        previous = self._tick_of[counter]
        if previous is not None:
            self._expired.discard(previous)
            self._late.discard(previous)
        self._tick_of[counter] = tick
        in_flight.append((tick, counter))
        return missed

    def _replied(self, tick: int) -> None:
        """A reply to ``tick``'s command came (usable or not): the silence before it is over."""
        self._newest_replied = max(self._newest_replied, tick)
        silent = self._silent
        while silent and silent[0] <= tick:
            silent.popleft()
        self.counts.unanswered_in_row = len(silent)

    def match(self, counter: int, next_tick: int) -> int | None:
        """The tick a reply with ``counter`` answers, if it may be used at ``next_tick``; else None."""
        tick = self._tick_of[counter]
        counts = self.counts
        in_flight = self._in_flight
        if tick is None:  # for no command this run sent
            counts.unmatched += 1
            return None
        if tick in self._expired:  # already counted missed; note that it came, too late
            self._expired.discard(tick)
            counts.ages[next_tick - tick] = counts.ages.get(next_tick - tick, 0) + 1
            counts.too_old += 1
            self._replied(tick)  # the link is alive
            return None
        if (tick in self._answered or tick in self._late
                or not in_flight or tick < in_flight[0][0]):
            counts.unmatched += 1  # a repeat of a reply already seen, or for no command in flight
            return None
        age = next_tick - tick
        counts.ages[age] = counts.ages.get(age, 0) + 1
        self._replied(tick)
        if age > self.max_age_ticks:
            counts.too_old += 1  # not used: it counts as missed when its command expires
            self._late.add(tick)
            return None
        self._answered.add(tick)
        counts.matched += 1
        if tick > self.newest_tick:
            self.newest_tick = tick
        return tick

    def usable(self, tick: int) -> bool:
        """Whether the newest sample may still be used at ``tick``."""
        return tick - self.newest_tick <= self.max_age_ticks
