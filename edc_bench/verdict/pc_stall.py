"""Was it the PC? A host stall right before an abort that a stalled bench causes.

A PC that stops the bench for longer than the rig's watchdog trips the rig ("rig fault: watchdog tripped"); one
that stops it for a while leaves replies unread, late or missing in a row. The abort then names the rig or the
bus, and the technician checks cables while the PC was the cause. The loop marks each tick a stall cost (the
trace's ``gap`` column) and each tick's lateness; a stall within :data:`WINDOW_S` before such an abort points at
the PC. Pure: trace columns and the abort in, a figure out.
"""

from __future__ import annotations

import math

import numpy as np

from edc_bench.config.models import Variant
from edc_bench.engine.abort_figures import (
    AmplifierOffFigures,
    HeartbeatLostFigures,
    RigFaultFigures,
    SilenceFigures,
    SlowLinkFigures,
)
from edc_bench.engine.outcome import Abort, AbortKind, RigFaultFlag
from edc_bench.protocol import FaultCode

#: How long before the abort a stall is looked for (s): the longest any of these aborts takes to be decided (the
#: heartbeat's timeout is the longest of them, a few hundred ms), with room.
WINDOW_S = 0.5

#: Aborts a stalled bench causes whatever the rig and the bus do.
_LINK_ABORTS = frozenset({AbortKind.SILENCE, AbortKind.SLOW_LINK, AbortKind.REPLIES_MISSING,
                          AbortKind.HEARTBEAT_LOST})


def a_stall_can_cause(abort: Abort) -> bool:
    """Whether a stall of the bench can cause ``abort``: the link's aborts, and the rig's watchdog (tripped while
    the test ran, or found tripped as the amplifier went off)."""
    if abort.kind in _LINK_ABORTS:
        return True
    if abort.kind is AbortKind.RIG_FAULT:
        return isinstance(abort.figures, RigFaultFigures) and RigFaultFlag.WATCHDOG_TRIPPED in abort.figures.flags
    if abort.kind is AbortKind.AMPLIFIER_OFF:
        return isinstance(abort.figures, AmplifierOffFigures) and abort.figures.fault_code == FaultCode.WATCHDOG.name
    return False


def stall_before_end_s(gap: np.ndarray, lateness_s: np.ndarray, period_s: float) -> float:
    """The longest host stall in the trace's last :data:`WINDOW_S` (s; 0.0: none).

    A run of ``n`` lost ticks (gap rows) stalled the bench for about ``n + 1`` periods; a tick that ran more than a
    period late, for its lateness.
    """
    window = max(1, int(round(WINDOW_S / period_s)))
    gap = np.asarray(gap, dtype=bool)[-window:]
    late = np.asarray(lateness_s, dtype=float)[-window:]
    longest = 0.0
    if gap.any():
        flags = np.concatenate(([0], gap.astype(np.int8), [0]))
        edges = np.flatnonzero(np.diff(flags))
        longest = float(np.max(edges[1::2] - edges[::2]) + 1) * period_s
    late = late[np.isfinite(late)]
    if len(late) and late.max() > period_s:
        longest = max(longest, float(late.max()))
    return longest


def shortest_cause_s(abort: Abort, variant: Variant) -> float:
    """The shortest stall of the bench that can cause ``abort`` (s): a stall shorter than this did not, and the
    abort's own cause (a cable, the rig) is what to check."""
    period_s = variant.controller.period_s
    figures = abort.figures
    if abort.kind in (AbortKind.RIG_FAULT, AbortKind.AMPLIFIER_OFF):  # the watchdog, less the ticks it takes
        return max(variant.rig.watchdog_ms * 1e-3 - 2 * period_s, period_s)
    if abort.kind in (AbortKind.SILENCE, AbortKind.SLOW_LINK):  # the replies of the stalled ticks, in a row
        limit = figures.limit if isinstance(figures, (SilenceFigures, SlowLinkFigures)) and figures.limit else \
            variant.acceptance.max_missed_replies_in_row
        return float(limit) * period_s
    if abort.kind is AbortKind.HEARTBEAT_LOST:  # the heartbeats go unread for half the timeout at least
        limit_ms = figures.limit_ms if isinstance(figures, HeartbeatLostFigures) else 0.0
        return (limit_ms if math.isfinite(limit_ms) else 0.0) * 1e-3 / 2
    return variant.acceptance.max_missed_replies_in_row * period_s  # replies missing: a run of them


def pc_stall_s(abort: Abort | None, trace: dict[str, np.ndarray], variant: Variant) -> float:
    """The host stall that points at the PC for ``abort`` (s; 0.0: none, one too short to cause it, or an abort a
    stall does not cause)."""
    if abort is None or not a_stall_can_cause(abort) or not len(trace.get("t_s", ())):
        return 0.0
    stall_s = stall_before_end_s(trace["gap"], trace["lateness_s"], variant.controller.period_s)
    return stall_s if stall_s >= shortest_cause_s(abort, variant) else 0.0


#: The reason for a link's abort when the rig is a process on this PC (the simulated rig): the PC did not run it in
#: time, whatever the bench's own ticks show
RIG_ON_THIS_PC_REASON = ("the rig is a process on this PC and stopped answering in time: most likely the PC did "
                         "not run it in time (other programs, or a virtual machine's host, held it up); there is no "
                         "CAN cable between them to check (a rig whose firmware breaks the protocol does this too: "
                         "edc-bench rig-check tells)")


def pc_stall_reason(stall_s: float, cpu_steal_s: float) -> str:
    """The reason's sentence for a stall that points at the PC."""
    steal = (f"; the hypervisor took {cpu_steal_s:.2f} s of CPU during the test" if cpu_steal_s >= 0.005 else "")
    return (f"the PC stalled: the bench stopped for {stall_s * 1e3:.0f} ms in the {WINDOW_S:g} s before the test "
            f"ended{steal}; such a stall ends a test this way whatever the rig and the bus do")
