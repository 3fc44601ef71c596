"""One loop, two clocks (docs/bench-test.md, "The loop").

:class:`SimulatedClock` never waits: it steps an in-process rig in lockstep,
one period per command, so a test is deterministic and runs as fast as the
computation allows. :class:`RealTimeClock` keeps absolute deadlines on
``perf_counter_ns`` (never ``sleep(period)``), sleeps coarsely, then
busy-waits the last stretch, and reports how late each tick started.
"""

from __future__ import annotations

import time
from abc import ABC, abstractmethod
from typing import Protocol


from edc_bench.runtime.clock_kind import ClockKind


def cpu_steal_s() -> float:
    """CPU time the hypervisor has taken from this machine (all cores), from /proc/stat.

    Returns 0 where the figure is not available. On a shared VM the tail of
    real-time lateness is set by steal, so it is reported beside timing.
    """
    try:
        with open("/proc/stat", encoding="ascii") as stat:
            fields = stat.readline().split()
        import os

        return int(fields[8]) / os.sysconf("SC_CLK_TCK")
    except (OSError, IndexError, ValueError):
        return 0.0


class LockstepRig(Protocol):
    """What the simulated clock needs of an in-process rig."""

    def service(self, now_s: float) -> None: ...

    def advance_to(self, t_s: float) -> None: ...


class Clock(ABC):
    """Time as the bench loop sees it."""

    #: True if replies arrive only after waiting (real time); False if the
    #: rig has answered by the time ``after_send`` returns (lockstep).
    waits_for_replies: bool = True
    #: Simulated or real time: what the record says of the test (a wrapper gives its inner clock's).
    kind: ClockKind = ClockKind.REAL_TIME

    def start(self) -> None:
        """Make now time 0."""

    @abstractmethod
    def now_s(self) -> float:
        """Seconds since :meth:`start`."""

    @abstractmethod
    def wait_until(self, t_s: float) -> float:
        """Return at time ``t_s`` (or at once if it has passed).

        Returns
        -------
        float
            Lateness in seconds: how long after ``t_s`` it returned.
        """

    def after_send(self, t_s: float) -> None:
        """Called after each frame the bench sends."""


class SimulatedClock(Clock):
    """Simulated time, stepping an in-process rig in lockstep.

    Parameters
    ----------
    rig : LockstepRig, optional
        Stepped to each new time; served after each send.
    """

    waits_for_replies = False
    kind = ClockKind.SIMULATED

    def __init__(self, rig: LockstepRig | None = None) -> None:
        self.rig = rig
        self._now = 0.0

    def start(self) -> None:
        """Simulated time starts at 0 when created; nothing to do."""

    def now_s(self) -> float:
        """Current simulated time."""
        return self._now

    def wait_until(self, t_s: float) -> float:
        """Advance simulated time (and the rig) to ``t_s``; never late."""
        if t_s > self._now:
            if self.rig is not None:
                self.rig.advance_to(t_s)
            self._now = t_s
        return 0.0

    def after_send(self, t_s: float) -> None:
        """Let the rig answer at once."""
        if self.rig is not None:
            self.rig.service(self._now)


class RealTimeClock(Clock):
    """Wall-clock time with absolute deadlines.

    Parameters
    ----------
    spin_s : float, optional
        The last stretch before a deadline is busy-waited, not slept.
    """

    def __init__(self, spin_s: float = 300e-6) -> None:
        self.spin_ns = int(spin_s * 1e9)
        self._t0_ns = time.perf_counter_ns()

    def start(self) -> None:
        """Make now time 0."""
        self._t0_ns = time.perf_counter_ns()

    def now_s(self) -> float:
        """Seconds since :meth:`start`."""
        return (time.perf_counter_ns() - self._t0_ns) * 1e-9

    @property
    def origin_ns(self) -> int:
        """``time.perf_counter_ns()`` at time 0 (CLOCK_MONOTONIC on Linux, shared by all processes)."""
        return self._t0_ns

    def wait_until(self, t_s: float) -> float:
        """Sleep, then spin, until ``t_s``; return the lateness."""
        target = self._t0_ns + int(t_s * 1e9)
        clock = time.perf_counter_ns
        remaining = target - clock()
        if remaining > self.spin_ns:
            time.sleep((remaining - self.spin_ns) * 1e-9)
        while clock() < target:
            pass
        return (clock() - target) * 1e-9
