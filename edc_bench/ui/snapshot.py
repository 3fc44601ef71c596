"""The state of a running test, copied out of the loop in a few microseconds for whoever shows it."""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from edc_bench.runtime.loop import Phase

if TYPE_CHECKING:
    from edc_bench.engine.outcome import PeriodDecision

PHASES = tuple(Phase)


@dataclass
class Snapshot:
    """Latest figures of the running test (written by the loop's thread, read by the view's)."""

    phase: str = Phase.CONNECT
    phases_done: list[str] = field(default_factory=list)
    tick: int = 0
    ticks: int = 0
    period_s: float = 0.001
    t_s: float = 0.0
    reference_mm: float = float("nan")
    position_mm: float = float("nan")
    current_a: float = float("nan")
    drive_v: float = float("nan")
    feedforward_v: float = float("nan")
    feedback_v: float = float("nan")
    af: float = float("nan")
    a1: float = float("nan")
    worst_lateness_recent_us: float = 0.0
    worst_lateness_us: float = 0.0
    ticks_late_or_lost: int = 0  # as the timing summary counts them against max_overrun_fraction
    missed_replies: int = 0
    bad_replies: int = 0
    heartbeats: int = 0
    rack_history: deque = field(default_factory=lambda: deque(maxlen=100))
    reference_history: deque = field(default_factory=lambda: deque(maxlen=100))
    af_history: list = field(default_factory=list)
    a1_history: list = field(default_factory=list)
    expected_end_s: float = float("nan")  # when the test is expected to end (early stop), NaN: at its full length
    expected_end_is_earliest: bool = True  # expected_end_s is only the earliest it can be (not decided on yet)
    period_fit: PeriodDecision | None = None  # the stop rule's last decision: what the verdict rests on

    def enter(self, name: str) -> None:
        """A new phase began."""
        if self.phase != name and self.phase not in self.phases_done:
            self.phases_done.append(self.phase)
        self.phase = name

    def update(self, k: int, loop: Any) -> None:
        """Copy tick ``k``'s figures out of a :class:`~edc_bench.runtime.loop.BenchLoop`."""
        self.apply(read_tick(k, loop))

    def apply(self, figures: dict[str, Any]) -> None:
        """Take the figures of one tick (from :func:`read_tick`) and extend the histories."""
        for name, value in figures.items():
            setattr(self, name, value)
        self.worst_lateness_us = max(self.worst_lateness_us, self.worst_lateness_recent_us)
        self.rack_history.append(self.position_mm)
        self.reference_history.append(self.reference_mm)
        self.af_history.append(self.af)
        self.a1_history.append(self.a1)

    @property
    def time_left_s(self) -> float:
        """Seconds of test expected to be left (to the expected early stop, else to the full length)."""
        end_s = self.expected_end_s if self.expected_end_s == self.expected_end_s else self.duration_s
        return max(min(end_s, self.duration_s) - self.tick * self.period_s, 0.0)

    @property
    def time_left_words(self) -> str:
        """How long the test has left, as the technician reads it: ``at least 10.0 s left (at most 30 s)`` with an
        early stop expected (``about`` once its time is estimated), ``12.0 s left`` without one."""
        if self.expected_end_s == self.expected_end_s:  # early stop: when the verdict is expected to be known
            how = "at least" if self.expected_end_is_earliest else "about"
            return f"{how} {self.time_left_s:4.1f} s left (at most {self.max_time_left_s:.0f} s)"
        return f"{self.time_left_s:4.1f} s left"

    @property
    def max_time_left_s(self) -> float:
        """Seconds left at most (the full length)."""
        return max(self.ticks - self.tick, 0) * self.period_s

    @property
    def duration_s(self) -> float:
        """Length of the test."""
        return self.ticks * self.period_s


def read_tick(k: int, loop: Any) -> dict[str, Any]:
    """The figures of tick ``k`` of a running loop, as plain numbers (a few microseconds; picklable)."""
    cols = loop.trace.columns
    recent = cols["lateness_s"][max(0, k - 99): k + 1]
    recent = recent[np.isfinite(recent)]  # ticks lost in a host stall have no lateness (NaN): counted, not shown
    outcome = loop.outcome
    rule = getattr(loop, "stop_rule", None)
    return {
        "tick": k, "ticks": loop.ticks, "period_s": loop.period_s, "t_s": float(cols["t_s"][k]),
        "reference_mm": float(cols["reference_mm"][k]), "position_mm": float(cols["position_mm"][k]),
        "current_a": float(cols["current_a"][k]), "drive_v": float(cols["drive_v"][k]),
        "feedforward_v": float(cols["feedforward_v"][k]), "feedback_v": float(cols["feedback_v"][k]),
        "af": float(cols["af_hat"][k]), "a1": float(cols["a1_hat"][k]),
        "worst_lateness_recent_us": float(np.max(recent)) * 1e6 if len(recent) else 0.0,
        "ticks_late_or_lost": outcome.ticks_late + outcome.ticks_lost, "missed_replies": outcome.missed_replies,
        "bad_replies": outcome.bad_replies, "heartbeats": outcome.heartbeats,
        "expected_end_s": float(getattr(rule, "expected_end_s", float("nan"))),
        "expected_end_is_earliest": bool(getattr(rule, "expected_end_is_earliest", True)),
        "period_fit": getattr(rule, "latest", None),  # frozen: shared with the loop's thread as it is
    }
