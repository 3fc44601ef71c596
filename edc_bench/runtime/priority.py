"""The bench's own scheduling priority for a test in real time: raised where the PC allows it, said where not.

A 1 kHz loop at normal priority shares its core with whatever else the PC runs (a virus scan, an update); one
such neighbour costs ticks, and the test is INVALID for the PC's sake. Under a real-time policy (Linux
SCHED_FIFO) the loop preempts them. A technician does not type ``chrt``: the bench asks for the policy itself,
for the thread that runs the test (the threads and the simulated rig process it starts inherit it), and gives it
back afterwards. Where the OS refuses (a user without an ``rtprio`` limit), the test runs at normal priority and
:func:`how_to_allow` says what the shop's administrator runs once to allow it; ``edc-bench check-station`` checks
the same.
"""

from __future__ import annotations

import contextlib
import os
import threading
from collections.abc import Iterator
from dataclasses import dataclass

#: The real-time priority the bench asks for (1-99): the kernel's interrupt threads run at 50 too, so the bench
#: never holds off the network card or the USB adapter it waits on; what ``chrt -f 50`` (the old advice) gave.
BENCH_PRIORITY = 50

#: How a test at normal priority for want of permission is recorded (what to do: :func:`how_to_allow`; the record
#: does not carry the login)
NOT_PERMITTED = "not permitted: the OS refused a real-time priority (edc-bench check-station says what to allow)"

#: The group a shop's administrator makes for the bench's users (:func:`how_to_allow`).
BENCH_GROUP = "edc-bench"


#: per thread: the priority this thread's :func:`realtime_priority` raised, while it holds
_raised = threading.local()


@dataclass(frozen=True)
class Priority:
    """The scheduling a test ran at.

    Attributes
    ----------
    realtime : bool
        The test's thread ran under a real-time policy.
    how : str
        ``raised`` (the bench raised it), ``inherited`` (started under one, ``chrt``), ``not permitted`` (the OS
        refused) or ``not available`` (not Linux).
    """

    realtime: bool
    how: str

    def describe(self) -> str:
        """For the record and the log: ``real-time (SCHED_FIFO 50, raised by the bench)``, ``normal (...)``."""
        if self.realtime:
            return f"real-time ({self.how})"
        return f"normal ({self.how})"


def realtime_now() -> bool:
    """Whether the calling thread runs under a real-time policy (SCHED_FIFO or SCHED_RR)."""
    try:
        return os.sched_getscheduler(0) in (os.SCHED_FIFO, os.SCHED_RR)
    except (AttributeError, OSError):
        return False


@contextlib.contextmanager
def realtime_priority(priority: int = BENCH_PRIORITY) -> Iterator[Priority]:
    """Run the block with the calling thread under SCHED_FIFO ``priority`` where the OS permits; restored after.

    Threads and processes the block starts inherit the policy (the simulated rig process is then raised one
    above, :func:`edc_bench.sim.process.above_the_bench`). Yields what the block runs at; never raises for a
    refusal.
    """
    outer = getattr(_raised, "priority", None)
    if outer is not None:  # inside the bench's own raise (the rig process's test): what that one said
        yield outer
        return
    if realtime_now():
        yield Priority(True, "inherited: the bench was started under a real-time policy")
        return
    try:
        before = os.sched_getscheduler(0), os.sched_getparam(0)
    except (AttributeError, OSError):
        yield Priority(False, "not available: this OS has no real-time policy the bench can ask for")
        return
    try:
        try:  # inside the try whose finally restores: an interrupt right after the raise leaves nothing raised
            os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))
        except OSError:  # EPERM: no rtprio limit, no CAP_SYS_NICE, a cgroup without a real-time budget
            yield Priority(False, NOT_PERMITTED)
            return
        _raised.priority = Priority(True, f"SCHED_FIFO {priority}, raised by the bench")
        yield _raised.priority
    finally:
        _raised.priority = None
        with contextlib.suppress(OSError):  # lowering one's own policy is always permitted
            os.sched_setscheduler(0, before[0], before[1])


def realtime_permitted() -> bool:
    """Whether this process may raise itself to :data:`BENCH_PRIORITY`: an ``rtprio`` limit that high, or the
    CAP_SYS_NICE capability (root has it, unless a container took it away)."""
    try:
        import resource

        soft, _ = resource.getrlimit(resource.RLIMIT_RTPRIO)
    except (ImportError, AttributeError, OSError, ValueError):
        return False
    if soft == resource.RLIM_INFINITY or soft >= BENCH_PRIORITY:
        return True
    return _has_cap_sys_nice()


#: Linux's CAP_SYS_NICE (capability.h): may set any scheduling policy
_CAP_SYS_NICE = 23


def _has_cap_sys_nice() -> bool:
    """CAP_SYS_NICE in the process's effective set (/proc/self/status); without /proc, whether it is root."""
    try:
        with open("/proc/self/status", encoding="ascii") as status:
            for line in status:
                if line.startswith("CapEff:"):
                    return bool(int(line.split()[1], 16) >> _CAP_SYS_NICE & 1)
    except (OSError, ValueError):
        pass
    return hasattr(os, "geteuid") and os.geteuid() == 0


def how_to_allow(user: str | None = None) -> str:
    """What the shop's administrator runs once so that the bench may raise its priority (Linux PAM limits)."""
    if user is None:
        try:  # the login the limit must name: the process's own, not what the environment says
            import pwd

            user = pwd.getpwuid(os.geteuid()).pw_name
        except (ImportError, KeyError, OSError):
            user = "<the technician's login>"
    return (f"real-time priority is not permitted for the user '{user}': the administrator runs, once, "
            f"'sudo groupadd -f {BENCH_GROUP} && sudo usermod -aG {BENCH_GROUP} {user} && "
            f"echo \"@{BENCH_GROUP} - rtprio {BENCH_PRIORITY}\" | sudo tee /etc/security/limits.d/{BENCH_GROUP}.conf'"
            f"; then log in again (edc-bench check-station checks it)")


def priority_notice(simulated: bool, *, permitted: bool | None = None, realtime: bool | None = None) -> str | None:
    """What a shift on a real rig is told once at its start when the bench cannot raise its priority (None: nothing
    to say: simulated time, permitted, or already real-time). ``permitted`` and ``realtime``: as found here by
    default."""
    if simulated:
        return None
    if realtime_now() if realtime is None else realtime:
        return None
    if permitted is None:  # asked of the OS, raised and given back at once: the limits do not tell it all
        with realtime_priority() as probe:
            permitted = probe.realtime
    if permitted:
        return None
    return ("tests run at normal priority on this PC, where a busy moment can make a test INVALID; "
            + how_to_allow())
