"""Host stalls on demand: a clock that wakes late now and then, as a busy or preempted bench PC does.

Wraps any :class:`~edc_bench.runtime.clock.Clock`. Every ``every_s`` of test
time, the wait for one deadline returns ``stall_s`` late: in simulated time
the stall simply passes (the rig runs on meanwhile, its watchdog too); in
real time the process really sleeps through it.
"""

from __future__ import annotations

import time

from edc_bench.runtime.clock import Clock


class StallingClock(Clock):
    """A clock whose waits overshoot by ``stall_s`` once every ``every_s``.

    Parameters
    ----------
    inner : Clock
        The clock to wrap.
    stall_s : float
        Length of each stall.
    every_s : float
        Time between stalls (the first comes after ``first_s``).
    first_s : float, optional
        Time of the first stall.
    """

    def __init__(self, inner: Clock, stall_s: float, every_s: float, first_s: float | None = None) -> None:
        self.inner = inner
        self.stall_s = stall_s
        self.every_s = every_s
        self.next_stall_s = every_s if first_s is None else first_s
        self.stalls = 0
        self.waits_for_replies = inner.waits_for_replies
        self.kind = inner.kind  # a stalled simulated test is simulated time still

    def start(self) -> None:
        """Start the inner clock."""
        self.inner.start()

    def now_s(self) -> float:
        """The inner clock's time."""
        return self.inner.now_s()

    def after_send(self, t_s: float) -> None:
        """Passed on to the inner clock."""
        self.inner.after_send(t_s)

    def wait_until(self, t_s: float) -> float:
        """Wait as the inner clock does, overshooting by the stall when one is due."""
        if t_s < self.next_stall_s:
            return self.inner.wait_until(t_s)
        self.next_stall_s += self.every_s
        self.stalls += 1
        late = self.inner.wait_until(t_s)
        if self.inner.waits_for_replies:
            time.sleep(self.stall_s)  # a real stall: the process does nothing meanwhile
            return max(late + self.stall_s, self.inner.now_s() - t_s)  # a sleep overshoots on a busy host
        self.inner.wait_until(t_s + self.stall_s)
        return late + self.stall_s
