"""The bench loop: the one place where time, bus I/O and controller math meet.

Phases: wait for the rig's READY heartbeat (re-arming a latched FAULT with
SAFE), a SAFE command to synchronise the counter and read the rack's start
position, then one RUN command per tick, each answered by a RIG_FEEDBACK
within the tick. Every way out, normal or not, ends with SAFE commands.

Per tick nothing is allocated beyond what python-can and the codec must:
the trace and the frame log are preallocated arrays.
"""

from __future__ import annotations

import enum
import gc
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Protocol

import can

from edc_bench.config.models import Variant
from edc_bench.control.design import build_controller
from edc_bench.control.fel import FelController
from edc_bench.protocol import (
    BENCH_CMD_ID,
    RIG_FEEDBACK_ID,
    RIG_HEARTBEAT_ID,
    FaultCode,
    Icd,
    Mode,
    RigFeedback,
    RigState,
)
from edc_bench.protocol.errors import ProtocolError
from edc_bench.runtime.clock import Clock, cpu_steal_s
from edc_bench.runtime.trace import CanFrameLog, Trace

# flag bits of trace column rig_flags
FLAG_AMP, FLAG_WATCHDOG, FLAG_OVER_CURRENT, FLAG_LVDT, FLAG_TRAVEL = 1, 2, 4, 8, 16


def reply_flags(reply: RigFeedback) -> int:
    """The reply's status bits as the trace's ``rig_flags`` column stores them."""
    return (reply.amp_enabled * FLAG_AMP | reply.watchdog_tripped * FLAG_WATCHDOG
            | reply.over_current * FLAG_OVER_CURRENT | reply.lvdt_fault * FLAG_LVDT
            | reply.travel_limit * FLAG_TRAVEL)


class Phase(enum.StrEnum):
    """The phases of a bench test, in order, as observers are told them."""

    CONNECT = "connect"
    WAIT_READY = "wait READY"
    SOFT_START = "soft start"
    IDENTIFY = "identify"
    SAFE_STOP = "safe stop"
    CLASSIFY = "classify"


#: Ticks between two :meth:`LoopObserver.tick` calls.
OBSERVE_EVERY = 100


class LoopObserver(Protocol):
    """Watches a test as it runs (the live view, log lines). Must return quickly: it runs inside the loop."""

    def phase(self, name: Phase) -> None:
        """The test entered phase ``name`` (:class:`Phase`; ``classify`` comes from
        :func:`~edc_bench.bench.run_bench_test`)."""

    def tick(self, k: int, loop: BenchLoop) -> None:
        """Tick ``k`` has been recorded (every :data:`OBSERVE_EVERY` ticks); read ``loop.trace``, ``loop.outcome``."""


@dataclass
class LoopOutcome:
    """What happened in the loop, beyond the trace."""

    ticks_planned: int
    ticks_run: int = 0
    missed_replies: int = 0
    max_missed_in_row: int = 0
    bad_replies: int = 0
    overruns: int = 0
    abort_reason: str | None = None
    rig_state_at_start: str | None = None
    fw_version: str | None = None
    safe_confirmed: bool = False
    heartbeats: int = 0
    cpu_steal_s: float = 0.0
    abort_time_s: float | None = None  # trace time at which the abort was decided
    ticks_start_s: float = 0.0  # clock time of trace time 0 (the frame log's time base)
    first_tick_unix_s: float | None = None  # wall-clock time the first tick began (start-up measurements)
    clock_origin_unix_s: float = 0.0  # Unix time of clock time 0 (the CAN log's timestamps are absolute)
    events: list[str] = field(default_factory=list)


class BenchLoop:
    """Runs one bench test on a bus with a clock.

    Parameters
    ----------
    bus : can.BusABC
        The bench's bus to the rig.
    clock : Clock
        Simulated (lockstep) or real time.
    variant : Variant
        Pump variant.
    icd : Icd
        The compiled ICD.
    observer : LoopObserver, optional
        Told the phases, and shown the loop every :data:`OBSERVE_EVERY` ticks.
    stop_requested : callable, optional
        Polled every tick and while waiting for the rig; True ends the test
        as an abort (the operator's Ctrl-C or SIGTERM).
    """

    def __init__(self, bus: can.BusABC, clock: Clock, variant: Variant, icd: Icd,
                 observer: LoopObserver | None = None, stop_requested: Callable[[], bool] | None = None) -> None:
        self.bus = bus
        self.clock = clock
        self.variant = variant
        self.icd = icd
        self.observer = observer
        self.stop_requested = stop_requested or (lambda: False)
        self.period_s = variant.controller.period_s
        self.ticks = int(round(variant.excitation.duration_s / self.period_s))
        self.trace = Trace(self.ticks)
        # a command and a reply per tick, heartbeats, and the phases around the ticks
        self.frames = CanFrameLog(2 * self.ticks + self.ticks // 50 + 4096)
        self.outcome = LoopOutcome(ticks_planned=self.ticks)
        self.controller: FelController | None = None
        self._counter = 0
        self._rig_state: RigState | None = None
        self._rig_fault_code = 0
        self._last_heartbeat_s = 0.0
        self._t_s = 0.0

    # -- frames ----------------------------------------------------------------
    def _send(self, mode: int, drive_v: float, reference_mm: float) -> int:
        self._counter = (self._counter + 1) & 0xFF
        data = self.icd.make_bench_cmd(self._counter, mode, drive_v, min(max(reference_mm, 0.0), 65.535))
        self.bus.send(can.Message(arbitration_id=BENCH_CMD_ID, data=data, is_extended_id=False))
        self.frames.add(self._t_s, BENCH_CMD_ID, data, False)
        self.clock.after_send(self._t_s)
        return self._counter

    def _receive(self, counter: int | None, deadline_s: float):
        """Read frames until the reply to ``counter`` or the deadline; log every frame."""
        bus, icd, clock = self.bus, self.icd, self.clock
        waits = clock.waits_for_replies
        while True:
            timeout = max(0.0, deadline_s - clock.now_s()) if waits else 0.0
            msg = bus.recv(timeout)
            if msg is None:
                return None
            now = clock.now_s() if waits else self._t_s
            self.frames.add(now, msg.arbitration_id, msg.data, True)
            can_id = msg.arbitration_id
            if can_id == RIG_FEEDBACK_ID and counter is not None:
                try:
                    reply = icd.parse_rig_feedback(msg.data)
                except ProtocolError:
                    self.outcome.bad_replies += 1
                    continue
                if reply.counter == counter:
                    return reply
            elif can_id == RIG_HEARTBEAT_ID:
                try:
                    beat = icd.parse_heartbeat(msg.data)
                except ProtocolError:
                    continue
                self.outcome.heartbeats += 1
                self._rig_state = beat.state
                self._rig_fault_code = beat.fault_code
                self._last_heartbeat_s = now
                if self.outcome.fw_version is None:
                    self.outcome.fw_version = f"{beat.fw_major}.{beat.fw_minor}"

    # -- phases ----------------------------------------------------------------
    def _wait_ready(self) -> bool:
        """Wait for READY, re-arming a FAULT with SAFE. False on timeout."""
        step = 0.01
        limit = self.variant.acceptance.ready_timeout_s
        rearmed = False
        while self._t_s < limit:
            if self.stop_requested():
                raise KeyboardInterrupt
            self._t_s += step
            self.clock.wait_until(self._t_s)
            self._receive(None, self._t_s + step * 0.5)
            if self.outcome.rig_state_at_start is None and self._rig_state is not None:
                self.outcome.rig_state_at_start = self._rig_state.name
            if self._rig_state is RigState.READY:
                return True
            if self._rig_state in (RigState.FAULT, RigState.RUNNING) and not rearmed:
                self.outcome.events.append(f"rig was {self._rig_state.name} at start: sent SAFE to re-arm")
                counter = self._send(Mode.SAFE, 0.0, 0.0)
                self._receive(counter, self._t_s + step * 0.5)
                rearmed = True
        return False

    def _safe_stop(self) -> None:
        """Send SAFE until the rig confirms its amplifier is off (up to 5 tries)."""
        for _ in range(5):
            self._t_s = max(self._t_s + self.period_s, self.clock.now_s())
            self.clock.wait_until(self._t_s)
            counter = self._send(Mode.SAFE, 0.0, 0.0)
            reply = self._receive(counter, self._t_s + 0.02)
            if reply is not None and not reply.amp_enabled:
                self.outcome.safe_confirmed = True
                return

    def _phase(self, name: Phase) -> None:
        if self.observer is not None:
            self.observer.phase(name)

    def run(self) -> LoopOutcome:
        """Run the test; always ends with SAFE. Returns what happened."""
        gc_was_enabled = gc.isenabled()
        gc.collect()
        gc.freeze()  # objects alive now are never scanned again
        gc.disable()  # and no collection interrupts a tick
        self.clock.start()
        self.frames.origin_unix_s = self.outcome.clock_origin_unix_s = time.time() - self.clock.now_s()
        steal_at_start = cpu_steal_s()
        try:
            self._phase(Phase.WAIT_READY)
            if not self._wait_ready():
                state = self._rig_state.name if self._rig_state else "no heartbeat"
                self.outcome.abort_reason = (
                    f"rig not READY within {self.variant.acceptance.ready_timeout_s:g} s ({state})"
                )
                return self.outcome
            self._run_ticks()
        except KeyboardInterrupt:
            self.outcome.abort_reason = "interrupted by the operator"
        except can.CanError as exc:
            self.outcome.abort_reason = f"bus error: {type(exc).__name__}: {exc}"
        except Exception as exc:  # noqa: BLE001 - a bug must not cost the rig's safety or the data
            import traceback

            self.outcome.abort_reason = f"internal error: {type(exc).__name__}: {exc}"
            self.outcome.events.append(traceback.format_exc())
        finally:
            try:
                self._phase(Phase.SAFE_STOP)
                self._safe_stop()  # run_bench_test's interrupt guard keeps a second Ctrl-C from skipping it
            except can.CanError as exc:
                self.outcome.events.append(f"SAFE could not be sent: {exc}")
            finally:
                self.outcome.cpu_steal_s = cpu_steal_s() - steal_at_start
                if gc_was_enabled:
                    gc.enable()
                gc.unfreeze()
        return self.outcome

    def _run_ticks(self) -> None:
        T = self.period_s
        # synchronise the counter and read where the rack is
        self._t_s += T
        self.clock.wait_until(self._t_s)
        counter = self._send(Mode.SAFE, 0.0, 0.0)
        # not time-critical: frames queued since connecting may come first
        first = self._receive(counter, self._t_s + 0.1)
        if first is None:
            self.outcome.abort_reason = "no reply to the first SAFE command"
            return
        position_mm = first.position_mm
        current_a = first.current_a
        self.controller = ctl = build_controller(self.variant, position_mm)

        trace = self.trace
        write_tick = trace.write_tick
        acceptance = self.variant.acceptance
        reply_window_s = T * acceptance.reply_timeout_fraction
        max_in_row = acceptance.max_missed_replies_in_row
        max_missed_fraction = acceptance.max_missed_reply_fraction
        heartbeat_timeout_s = self.variant.rig.heartbeat_period_ms * 1e-3 * acceptance.heartbeat_timeout_periods
        max_error_mm = acceptance.max_tracking_error_mm
        error_ticks_limit = acceptance.tracking_error_ticks
        error_ticks = 0
        follow_from_k = int(self.variant.excitation.move_s / T)  # the rack must follow once it has arrived
        rig = self.variant.rig
        position_range = (rig.travel_min_mm - 1.0, self.variant.rack.stroke_mm + 1.0)
        self._last_heartbeat_s = max(self._last_heartbeat_s, self._t_s)
        t_start = max(self._t_s, self.clock.now_s()) + T
        outcome = self.outcome
        outcome.ticks_start_s = t_start
        missed_in_row = 0
        observer = self.observer
        identify_from_k = int(round((self.variant.excitation.move_s + self.variant.excitation.fade_s) / T))
        clock = self.clock
        self._phase(Phase.SOFT_START)

        stop_requested = self.stop_requested
        for k in range(self.ticks):
            if stop_requested():
                outcome.abort_time_s = k * T
                outcome.abort_reason = "interrupted by the operator"
                return
            t_k = t_start + k * T
            self._t_s = t_k
            lateness = clock.wait_until(t_k)
            if lateness > T:
                outcome.overruns += 1
            if k == 0:
                outcome.first_tick_unix_s = time.time()
            u = ctl.step(k, position_mm)
            sent_s = clock.now_s()
            counter = self._send(Mode.RUN, u, ctl.reference_mm)
            reply = self._receive(counter, t_k + reply_window_s)
            reply_latency_s = clock.now_s() - sent_s if reply is not None else math.nan
            if reply is None:
                outcome.missed_replies += 1
                missed_in_row += 1
                outcome.max_missed_in_row = max(outcome.max_missed_in_row, missed_in_row)
                flags = 0
            else:
                missed_in_row = 0
                position_mm, current_a = reply.position_mm, reply.current_a
                flags = reply_flags(reply)
            write_tick(k, t_k - t_start, lateness, reply_latency_s, ctl, position_mm, current_a, u, reply is not None,
                       flags)
            outcome.ticks_run = k + 1
            if reply is not None and reply.any_fault:
                outcome.abort_time_s = t_k - t_start
                outcome.abort_reason = "rig fault: " + ", ".join(
                    name for name, bit in (("watchdog tripped", reply.watchdog_tripped),
                                           ("over-current", reply.over_current),
                                           ("LVDT fault", reply.lvdt_fault),
                                           ("travel limit", reply.travel_limit)) if bit
                )
                return
            if reply is not None and not reply.amp_enabled:
                outcome.abort_time_s = t_k - t_start
                state = self._rig_state.name if self._rig_state is not None else "unknown"
                outcome.abort_reason = (f"rig amplifier off while running (rig state {state}, "
                                        f"fault code {FaultCode(self._rig_fault_code).name})")
                return
            if missed_in_row > max_in_row:
                outcome.abort_reason = f"{missed_in_row} replies missing in a row (limit {max_in_row})"
            elif k >= 1000 and outcome.missed_replies > max_missed_fraction * (k + 1):
                outcome.abort_reason = (f"{outcome.missed_replies} of {k + 1} replies missing "
                                        f"(limit {max_missed_fraction:.1%})")
            elif t_k - self._last_heartbeat_s > heartbeat_timeout_s:
                outcome.abort_reason = (f"rig heartbeat lost: none for {(t_k - self._last_heartbeat_s) * 1e3:.0f} ms "
                                        f"(limit {heartbeat_timeout_s * 1e3:.0f} ms)")
            elif self._rig_state is RigState.FAULT:
                outcome.abort_reason = f"rig reported FAULT (fault code {FaultCode(self._rig_fault_code).name})"
            elif not (position_range[0] <= position_mm <= position_range[1]) or abs(current_a) > rig.over_current_a:
                outcome.abort_reason = (f"sample out of range: rack {position_mm:.3f} mm, coil {current_a:.3f} A "
                                        f"(plausible {position_range[0]:g}..{position_range[1]:g} mm, "
                                        f"|i| <= {rig.over_current_a:g} A)")
            else:
                error_ticks = error_ticks + 1 if k > follow_from_k and abs(ctl.reference_mm - position_mm) > max_error_mm else 0
                if error_ticks >= error_ticks_limit:
                    outcome.abort_reason = (f"rack does not follow its reference: more than {max_error_mm:g} mm off "
                                            f"for {error_ticks} ticks (stuck rack or sensor)")
            if outcome.abort_reason is not None:
                outcome.abort_time_s = t_k - t_start
                return
            if observer is not None:
                if k % OBSERVE_EVERY == 0:
                    observer.tick(k, self)
                if k == identify_from_k:
                    observer.phase(Phase.IDENTIFY)
