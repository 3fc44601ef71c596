"""Did this machine, not the code, decide a real-time run? One judge for every real-time test.

A real-time test over the rig process fails only when the run was not disturbed: on a shared 2-core machine
(CI's, a loaded developer's) either process can be held off the CPU for milliseconds. Every sign the run's
record gives is looked at; a test that did not get its result from a disturbed run skips, printing them.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

import pytest

from edc_bench.engine.tick_timing import TickTiming

STEAL_LIMIT_S = 0.15  # CPU steal during one run above which real-time figures say nothing about the code
STALL_LIMIT_US = 10_000  # a bench tick this late means the machine did not run the process
# with the shipped acceptance a test ends when 6 commands in a row pass the 4 ms age limit with no reply at all:
# a rig process that does not serve for 8 ms (less the adapter's round trip) gets there
RIG_GAP_LIMIT_MS = 8.0
# a bench process that lost more than 1 tick in 500 to stalls of its own (each a whole period late) was not given
# its 1 kHz by this machine: the shipped acceptance allows 1 % of ticks, and the stall test spends half of that
OWN_LOSS_LIMIT = 0.002
OWN_LOSS_MIN_TICKS = 5  # below this a short (aborted) run's own losses say nothing: one stall of 1 ms is not a machine


def lost_too_many(lost: int, ticks_run: int) -> bool:
    """The bench process lost more ticks to stalls of its own than this machine is allowed to cost it."""
    return lost > max(OWN_LOSS_LIMIT * ticks_run, OWN_LOSS_MIN_TICKS)


def disturbance(timing: Mapping[str, Any] | TickTiming, rig: Mapping[str, Any] | None,
                lost: tuple[int, int] | None = None) -> str:
    """What this machine did to a run ("" if nothing): from its ``timing`` (the record's), the rig process's
    status ``rig`` (``worst_gap_ms``) and ``lost`` = (ticks the bench lost to stalls of its own, ticks run)."""
    timing = dict(timing)  # a record's mapping, or a result's TickTiming
    found = []
    if timing["cpu_steal_s"] >= STEAL_LIMIT_S:
        found.append(f"CPU steal {timing['cpu_steal_s']:.2f} s")
    worst = timing.get("lateness_max_us")
    if worst is not None and worst >= STALL_LIMIT_US:
        found.append(f"a tick {worst / 1e3:.1f} ms late")
    rig_gap = (rig or {}).get("worst_gap_ms")
    if rig_gap is None:
        found.append("the rig process reported no serve gap")
    elif rig_gap >= RIG_GAP_LIMIT_MS:
        found.append(f"the rig process did not serve for {rig_gap} ms")
    if lost is not None and lost_too_many(*lost):
        found.append(f"the bench lost {lost[0]} of {lost[1]} ticks to stalls of its own")
    return "; ".join(found)


def figures(timing: Mapping[str, Any] | TickTiming, rig: Mapping[str, Any] | None) -> str:
    """The run's timing figures, as a failure or skip message prints them."""
    timing = dict(timing)  # a record's mapping, or a result's TickTiming
    return (f"steal {timing['cpu_steal_s']:.2f} s, worst tick {(timing.get('lateness_max_us') or 0) / 1e3:.1f} ms "
            f"late, stop check {(timing.get('stop_check_max_us') or 0) / 1e3:.1f} ms, rig's worst serve gap "
            f"{(rig or {}).get('worst_gap_ms')} ms")


def attempts(run: Callable[[], tuple[bool, str, str]], what: str, tries: int = 3) -> bool:
    """Run ``run()`` until an attempt completes or is undisturbed, and return whether it completed; skip if
    every attempt was disturbed and none completed.

    ``run`` returns (completed, description, disturbance): ``disturbance`` is :func:`disturbance`'s finding
    ("" if none). A completed attempt passes, disturbed or not (the disturbance excuses a failure, it does not
    spoil a success; ``run`` has checked the completed run's figures); an undisturbed attempt that did not
    complete ends the attempts (the caller fails); only when every attempt was disturbed and failed is the test
    skipped, with every attempt's figures.
    """
    seen = []
    for attempt in range(tries):
        completed, description, machine = run()
        print(f"{what}, attempt {attempt + 1}: {description}; machine: {machine or '-'}")
        seen.append(f"{description}: {machine}")
        if completed or not machine:
            return completed
    pytest.skip(f"{what}: every attempt was disturbed by this machine: " + " | ".join(seen))
