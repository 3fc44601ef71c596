"""The bench loop: the one place where time, bus I/O and controller math meet.

Phases: wait for the rig's READY heartbeat (re-arming a latched FAULT with
SAFE), a SAFE command to synchronise the counter and read the rack's start
position, then one RUN command per tick. Every way out, normal or not, ends
with SAFE commands.

The ticks are pipelined (firmware_proto/PROTOCOL.md, "Timing"): a command
goes out on its tick whatever the replies do; between ticks the loop reads
what the bus brings, for the time left until the next deadline and at most
``max_frames_per_tick`` frames, and :class:`~edc_bench.runtime.replies.ReplyMatcher`
matches each reply to its command by counter, up to ``max_reply_age_ms``.
The controller uses the newest sample and knows its tick. A host stall that
costs whole periods is a gap: the lost ticks are marked in the trace and
skipped, never sent late in a burst.

Per tick nothing is allocated beyond what python-can and the codec must:
the trace and the frame log are preallocated arrays.
"""

from __future__ import annotations

import enum
import gc
import math
import time
from collections.abc import Callable, Container
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
from edc_bench.runtime.replies import SYNC_TICK, ReplyMatcher, max_reply_age_ticks, stale_limit_ticks
from edc_bench.runtime.trace import CanFrameLog, Trace, frame_flags
from edc_bench.runtime.tracking import OffReferenceRun

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
#: How often the loop looks for the rig's READY heartbeat before the test (s).
_READY_STEP_S = 0.01


class StopRule(Protocol):
    """Decides whether a test may end before its full length (:class:`~edc_bench.diagnosis.early_stop.EarlyStop`)."""

    #: ticks after which :meth:`check` is asked (the ends of whole excitation periods, and steps of work spread
    #: between them); each call must be short (it runs inside a tick: at most a tick or two late after it)
    check_ticks: Container[int]
    #: when the test is expected to end (trace time, s), for the live view
    expected_end_s: float

    def check(self, k: int, columns: dict) -> dict | None:
        """At tick ``k``: the reason to stop now (a dict with ``reason`` and ``time_s``), or None."""


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
    max_missed_in_row: int = 0  # commands in a row without a usable reply (the PID held meanwhile)
    max_unanswered_in_row: int = 0  # commands in a row with no reply at all
    bad_replies: int = 0
    overruns: int = 0  # ticks that started a period or more late (each a host stall, ending in a gap)
    abort_reason: str | None = None
    rig_state_at_start: str | None = None
    fw_version: str | None = None
    safe_confirmed: bool = False
    heartbeats: int = 0
    cpu_steal_s: float = 0.0
    abort_time_s: float | None = None  # trace time at which the abort was decided
    ticks_start_s: float = 0.0  # clock time of trace time 0 (the frame log's time base)
    first_tick_unix_s: float | None = None  # wall-clock time the first tick began (start-up measurements)
    replies_too_old: int = 0  # replies that came after max_reply_age_ms: never used
    gaps: int = 0  # host stalls that cost whole periods
    ticks_lost: int = 0  # ticks skipped in those gaps
    reply_age_ticks: dict[int, int] = field(default_factory=dict)  # age at arrival (ticks) -> replies
    clock_origin_unix_s: float = 0.0  # Unix time of clock time 0 (the CAN log's timestamps are absolute)
    other_frames: int = 0  # frames of no ICD message: other nodes' traffic, extended, remote or error frames
    bus_bad_lines: int = 0  # lines the bus driver could not read as frames (slcan), skipped
    bus_bad_line_samples: list[str] = field(default_factory=list)
    bus_device_errors: int = 0  # the adapter answered BEL: it refused a command of ours (slcan)
    frames_dropped: int = 0  # frames beyond the CAN log's maximum, counted but not stored
    events: list[str] = field(default_factory=list)
    stop: dict | None = None  # the stop rule's decision, when it ended the test early
    stop_check_max_s: float = 0.0  # the stop rule's longest call (wall time, perf_counter)


class _AbortTest(Exception):
    """The bus did something that ends the test; the message is the reason."""


class _BusFlooded(_AbortTest):
    """More frames arrived in one tick than the loop will read."""


class _ForeignCommand(_AbortTest):
    """Another node on the bus sends BENCH_CMD: two hosts would be driving one rig."""


FOREIGN_COMMAND_REASON = ("another host is sending BENCH_CMD on the bus: a second bench or tool is driving the "
                          "rig; stop it, then test again")


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
    stop_rule : StopRule, optional
        Asked at the end of each excitation period whether the test may end now (early stop); the test runs
        its full length without one.
    """

    def __init__(self, bus: can.BusABC, clock: Clock, variant: Variant, icd: Icd,
                 observer: LoopObserver | None = None, stop_requested: Callable[[], bool] | None = None,
                 stop_rule: StopRule | None = None) -> None:
        self.stop_rule = stop_rule
        self.bus = bus
        self.clock = clock
        self.variant = variant
        self.icd = icd
        self.observer = observer
        self.stop_requested = stop_requested or (lambda: False)
        self.period_s = variant.controller.period_s
        self.ticks = int(round(variant.excitation.duration_s / self.period_s))
        self.trace = Trace(self.ticks)
        # what the loop can read at most: the frame budget at each of a tick's two reads and each wait step for
        # READY, its own command per tick, the safe stop; a busy or hostile bus is logged whole (the arrays take
        # memory only as frames fill them)
        budget = variant.acceptance.max_frames_per_tick
        ready_steps = int(variant.acceptance.ready_timeout_s / _READY_STEP_S) + 2
        self.frames = CanFrameLog((2 * budget + 1) * self.ticks + (budget + 1) * (ready_steps + 10) + 4096)
        self.outcome = LoopOutcome(ticks_planned=self.ticks)
        self.controller: FelController | None = None
        self._counter = 0
        self._rig_state: RigState | None = None
        self._rig_fault_code = 0
        self._last_heartbeat_s = 0.0
        self._t_s = 0.0
        self.max_frames_per_tick = variant.acceptance.max_frames_per_tick
        self.matcher = ReplyMatcher(max_reply_age_ticks(variant))
        self._sent_s = [0.0] * self.ticks
        self.position_mm = math.nan
        self.current_a = math.nan
        self.newest_reply: RigFeedback | None = None
        self.newest_flags = 0  # its status bits as the trace stores them
        self._foreign_command: str | None = None  # set when another host's BENCH_CMD came outside the ticks
        self._sent_any = False

    # -- frames ----------------------------------------------------------------
    def _send(self, mode: int, drive_v: float, reference_mm: float, counter: int | None = None) -> int:
        self._counter = (self._counter + 1) & 0xFF if counter is None else counter
        self._sent_any = True
        data = self.icd.make_bench_cmd(self._counter, mode, drive_v, min(max(reference_mm, 0.0), 65.535))
        self.bus.send(can.Message(arbitration_id=BENCH_CMD_ID, data=data, is_extended_id=False))
        self.frames.add(self.clock.now_s() if self.clock.waits_for_replies else self._t_s, BENCH_CMD_ID, data, False)
        self.clock.after_send(self._t_s)
        return self._counter

    def _read(self, until_s: float) -> tuple[can.Message | None, float]:
        """The next frame, waiting at most until ``until_s`` (never, in lockstep); logged. (None, now) at the end."""
        clock = self.clock
        if clock.waits_for_replies:
            timeout = until_s - clock.now_s()
            msg = self.bus.recv(timeout) if timeout > 0.0 else self.bus.recv(0.0)
            now = clock.now_s()
        else:
            msg, now = self.bus.recv(0.0), self._t_s
        if msg is not None:
            self.frames.add(now, msg.arbitration_id, msg.data, True, frame_flags(msg), msg.dlc)
        return msg, now

    def _is_foreign_command(self, msg: can.Message) -> bool:
        """A valid BENCH_CMD on the bus that this bench did not send (an interface echoing our own frames is no host).

        Only a command the rig would obey counts (its CRC checked): a damaged frame with the id is no second host.
        """
        if not msg.is_rx:  # python-can marks an interface's echo of our own frame (receive_own_messages)
            return False
        try:
            self.icd.parse_bench_cmd(msg.data)
        except ProtocolError:
            return False
        data, frames = bytes(msg.data), self.frames
        for k in range(frames.count - 1, max(-1, frames.count - 1024), -1):  # rare: only when one comes
            if not frames.rx[k] and frames.can_id[k] == BENCH_CMD_ID and bytes(frames.data[k, : frames.dlc[k]]) == data:
                return False
        return True

    def _not_icd(self, msg: can.Message) -> bool:
        """True (and counted) for a frame that is no ICD message from the rig; raises for another host's command."""
        if msg.is_extended_id or msg.is_remote_frame or msg.is_error_frame:
            self.outcome.other_frames += 1
            return True
        can_id = msg.arbitration_id
        if can_id == BENCH_CMD_ID:
            if self._is_foreign_command(msg):
                self.outcome.other_frames += 1
                raise _ForeignCommand(FOREIGN_COMMAND_REASON)
            return True
        if can_id != RIG_FEEDBACK_ID and can_id != RIG_HEARTBEAT_ID:
            self.outcome.other_frames += 1
            return True
        return False

    def _heartbeat(self, data: bytes | bytearray, now: float) -> None:
        try:
            beat = self.icd.parse_heartbeat(data)
        except ProtocolError:
            return
        self.outcome.heartbeats += 1
        self._rig_state = beat.state
        self._rig_fault_code = beat.fault_code
        self._last_heartbeat_s = now
        if self.outcome.fw_version is None:
            self.outcome.fw_version = f"{beat.fw_major}.{beat.fw_minor}"

    def _receive(self, counter: int | None, deadline_s: float) -> RigFeedback | None:
        """Outside the ticks: read until the reply to ``counter`` or the deadline, at most a tick's frame budget."""
        frames = 0
        while frames < self.max_frames_per_tick:
            msg, now = self._read(deadline_s)
            if msg is None:
                if counter is None or self.clock.waits_for_replies or self._t_s >= deadline_s:
                    return None
                # simulated time: let it pass in small steps, so a reply on its way through an adapter arrives
                self._t_s = min(deadline_s, self._t_s + 0.25 * self.period_s)
                self.clock.wait_until(self._t_s)
                continue
            frames += 1
            try:
                if self._not_icd(msg):
                    continue
            except _ForeignCommand as foreign:
                self._foreign_command = str(foreign)
                continue
            if msg.arbitration_id == RIG_FEEDBACK_ID and counter is not None:
                try:
                    reply = self.icd.parse_rig_feedback(msg.data)
                except ProtocolError:
                    self.outcome.bad_replies += 1
                    continue
                if reply.counter == counter:
                    return reply
            elif msg.arbitration_id == RIG_HEARTBEAT_ID:
                self._heartbeat(msg.data, now)
        self.outcome.events.append(f"more than {self.max_frames_per_tick} frames while waiting for a reply")
        return None

    def _drain(self, next_tick: int, until_s: float) -> None:
        """Between ticks: read what comes until ``until_s``, match replies, keep the newest sample.

        Raises
        ------
        _BusFlooded
            More than the frame budget arrived within one tick.
        _ForeignCommand
            Another host sent BENCH_CMD.
        """
        matcher, icd, outcome, trace = self.matcher, self.icd, self.outcome, self.trace
        for _ in range(self.max_frames_per_tick):
            msg, now = self._read(until_s)
            if msg is None:
                return
            if self._not_icd(msg):
                continue
            can_id = msg.arbitration_id
            if can_id == RIG_FEEDBACK_ID:
                try:
                    reply = icd.parse_rig_feedback(msg.data)
                except ProtocolError:
                    outcome.bad_replies += 1
                    continue
                tick = matcher.match(reply.counter, next_tick)
                if tick is None:
                    continue
                flags = reply_flags(reply)
                trace.reply_arrived(tick, now - self._sent_s[tick], reply.position_mm, reply.current_a, flags)
                self.controller.add_sample(tick, reply.position_mm, reply.current_a)
                if tick == matcher.newest_tick:
                    self.position_mm, self.current_a, self.newest_reply = reply.position_mm, reply.current_a, reply
                    self.newest_flags = flags
            elif can_id == RIG_HEARTBEAT_ID:
                self._heartbeat(msg.data, now)
        raise _BusFlooded(f"bus flooded: more than {self.max_frames_per_tick} frames within one tick "
                          f"(acceptance.max_frames_per_tick)")

    # -- phases ----------------------------------------------------------------
    def _wait_ready(self) -> bool:
        """Wait for READY, re-arming a FAULT with SAFE. False on timeout."""
        step = _READY_STEP_S
        limit = self.variant.acceptance.ready_timeout_s
        rearmed = False
        while self._t_s < limit:
            if self.stop_requested():
                raise KeyboardInterrupt
            self._t_s += step
            self.clock.wait_until(self._t_s)
            self._receive(None, self._t_s + step * 0.5)
            if self._foreign_command is not None:
                raise _ForeignCommand(self._foreign_command)  # never send SAFE into another host's test
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
        except _AbortTest as abort:
            self.outcome.abort_reason = str(abort)
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
                if self._sent_any or self.outcome.abort_reason != FOREIGN_COMMAND_REASON:
                    self._safe_stop()  # run_bench_test's interrupt guard keeps a second Ctrl-C from skipping it
                else:  # never break into another host's test with a SAFE of ours
                    self.outcome.events.append("no SAFE sent: this bench never commanded the rig, another host does")
            except can.CanError as exc:
                self.outcome.events.append(f"SAFE could not be sent: {exc}")
            finally:
                self.outcome.cpu_steal_s = cpu_steal_s() - steal_at_start
                self.outcome.reply_age_ticks = dict(sorted(self.matcher.counts.ages.items()))
                self.outcome.replies_too_old = self.matcher.counts.too_old
                self._note_bus_figures()
                if gc_was_enabled:
                    gc.enable()
                gc.unfreeze()
        return self.outcome

    def _note_bus_figures(self) -> None:
        """What the bus driver skipped and the frame log could not hold, for the record."""
        outcome, frames = self.outcome, self.frames
        outcome.frames_dropped = frames.dropped
        if frames.dropped:
            outcome.events.append(f"CAN log full: {frames.dropped} frames after the first {frames.count} were "
                                  "counted but not stored")
        outcome.bus_bad_lines = int(getattr(self.bus, "bad_lines", 0))
        outcome.bus_bad_line_samples = [repr(line) for line in getattr(self.bus, "bad_line_samples", [])]
        outcome.bus_device_errors = int(getattr(self.bus, "device_errors", 0))
        if outcome.bus_device_errors and outcome.abort_reason is not None:
            outcome.abort_reason += (f"; the CAN adapter refused {outcome.bus_device_errors} of our frames (BEL): "
                                     "with edc-bench rig, another host may own the rig")

    def _run_ticks(self) -> None:
        T = self.period_s
        # synchronise the counter and read where the rack is
        self._t_s += T
        self.clock.wait_until(self._t_s)
        counter = self._send(Mode.SAFE, 0.0, 0.0)
        # not time-critical: frames queued since connecting may come first
        first = self._receive(counter, self._t_s + 0.1)
        if self._foreign_command is not None:
            raise _ForeignCommand(self._foreign_command)
        if first is None:
            self.outcome.abort_reason = "no reply to the first SAFE command"
            return
        self.position_mm, self.current_a = first.position_mm, first.current_a
        run_base = (counter + 1) & 0xFF  # tick k's command carries counter run_base + k
        self.controller = ctl = build_controller(self.variant, self.position_mm)
        ctl.add_sample(SYNC_TICK, self.position_mm)

        trace, matcher, sent_s = self.trace, self.matcher, self._sent_s
        acceptance = self.variant.acceptance
        max_in_row = acceptance.max_missed_replies_in_row
        # without a usable sample the PID holds; as long as the rig's watchdog lets a silent bench go (the
        # replies still coming, too late: a link that held them back once), the test goes on
        max_stale_in_row = stale_limit_ticks(self.variant)
        stale_limit_source = ("the rig's watchdog time" if max_stale_in_row > max_in_row
                              else "acceptance.max_missed_replies_in_row")
        max_missed_fraction = acceptance.max_missed_reply_fraction
        heartbeat_timeout_s = self.variant.rig.heartbeat_period_ms * 1e-3 * acceptance.heartbeat_timeout_periods
        off_reference = OffReferenceRun(acceptance.max_tracking_error_mm, acceptance.tracking_error_ticks)
        follow_from_k = int(self.variant.excitation.move_s / T)  # the rack must follow once it has arrived
        rig = self.variant.rig
        position_range = (rig.travel_min_mm - 1.0, self.variant.rack.stroke_mm + 1.0)
        self._last_heartbeat_s = max(self._last_heartbeat_s, self._t_s)
        t_start = max(self._t_s, self.clock.now_s()) + T
        outcome = self.outcome
        outcome.ticks_start_s = t_start
        observer = self.observer
        identify_from_k = int(round((self.variant.excitation.move_s + self.variant.excitation.fade_s) / T))
        clock = self.clock
        # real time: read replies until half a period before the next deadline (a wake-up from the read can be
        # late on a busy host), then the clock spins to it; what arrives meanwhile is read before the next step
        read_margin_s = 0.5 * T
        self._phase(Phase.SOFT_START)

        stop_requested, stop_rule = self.stop_requested, self.stop_rule
        k, last_run = 0, -1
        while k < self.ticks:
            if stop_requested():
                outcome.abort_time_s = k * T
                outcome.abort_reason = "interrupted by the operator"
                return
            t_k = t_start + k * T
            self._t_s = t_k
            lateness = clock.wait_until(t_k)
            if lateness >= T:
                # a host stall cost whole periods: skip them (a gap), never send them late in a burst; counted
                # from now, not from the wake-up, so the tick after the gap is on time even if the stall went on
                if clock.waits_for_replies:
                    lateness = max(lateness, clock.now_s() - t_k)
                lost = min(int(lateness // T), self.ticks - k)
                for g in range(k, k + lost):
                    trace.write_gap(g, (t_start + g * T) - t_start, ctl)
                outcome.overruns += 1  # shown live; the judgement counts the lost ticks (ticks_lost)
                outcome.gaps += 1
                outcome.ticks_lost += lost
                k += lost
                if k >= self.ticks:
                    outcome.ticks_run = k
                    return
                ctl.resync()
                t_k = t_start + k * T
                self._t_s = t_k
                lateness = max(0.0, clock.now_s() - t_k) if clock.waits_for_replies else 0.0
            if k == 0:
                outcome.first_tick_unix_s = time.time()
            try:
                # what came while waiting for this deadline (matched as the last drain did: replay sees the
                # same frames between the same two commands); the sample is used only if young enough at tick k
                self._drain(last_run + 1, clock.now_s())
            except _AbortTest as abort:
                outcome.abort_time_s = t_k - t_start
                outcome.abort_reason = str(abort)
                return
            u = ctl.step(k, newest_usable=matcher.usable(k))
            sent_s[k] = clock.now_s()
            self._send(Mode.RUN, u, ctl.reference_mm, (run_base + k) & 0xFF)
            matcher.sent(k, (run_base + k) & 0xFF)
            trace.write_tick(k, t_k - t_start, lateness, math.nan, ctl, self.position_mm, self.current_a, u, False,
                             self.newest_flags, k - matcher.newest_tick)
            outcome.ticks_run = k + 1
            last_run = k
            try:
                self._drain(k + 1, t_k + T - read_margin_s)
            except _AbortTest as abort:
                outcome.abort_time_s = t_k - t_start
                outcome.abort_reason = str(abort)
                return
            counts = matcher.counts
            outcome.missed_replies = counts.missed
            outcome.max_missed_in_row = counts.max_missed_in_row
            outcome.max_unanswered_in_row = counts.max_unanswered_in_row
            reply, position_mm, current_a = self.newest_reply, self.position_mm, self.current_a
            if reply is not None and reply.any_fault:
                outcome.abort_reason = "rig fault: " + ", ".join(
                    name for name, bit in (("watchdog tripped", reply.watchdog_tripped),
                                           ("over-current", reply.over_current),
                                           ("LVDT fault", reply.lvdt_fault),
                                           ("travel limit", reply.travel_limit)) if bit
                )
            elif reply is not None and not reply.amp_enabled:
                state = self._rig_state.name if self._rig_state is not None else "unknown"
                outcome.abort_reason = (f"rig amplifier off while running (rig state {state}, "
                                        f"fault code {FaultCode(self._rig_fault_code).name})")
            elif counts.unanswered_in_row > max_in_row:
                why = (f"no valid reply ({outcome.bad_replies} failed their CRC check in this test)"
                       if outcome.bad_replies else "the rig stopped answering")
                outcome.abort_reason = (f"{counts.unanswered_in_row} replies missing in a row (limit {max_in_row}): "
                                        f"{why}")
                if counts.too_old:
                    outcome.abort_reason += f" ({counts.too_old} replies came earlier, too old to use)"
            elif counts.missed_in_row > max_stale_in_row:
                outcome.abort_reason = (
                    f"no usable reply for {counts.missed_in_row} ticks in a row (limit {max_stale_in_row}, "
                    f"{stale_limit_source}); {counts.too_old} replies came, but older than "
                    f"acceptance.max_reply_age_ms ({acceptance.max_reply_age_ms:g} ms): the link is slower than the "
                    "variant's gains are checked for (raise max_reply_age_ms and retune the gains for that delay)")
            elif k >= 1000 and counts.missed > max_missed_fraction * (k + 1):
                outcome.abort_reason = (f"{counts.missed} of {k + 1} replies missing "
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
            elif k > follow_from_k:
                outcome.abort_reason = off_reference.update(ctl.reference_mm, position_mm)
            if outcome.abort_reason is not None:
                outcome.abort_time_s = t_k - t_start
                return
            if observer is not None:
                if k % OBSERVE_EVERY == 0:
                    observer.tick(k, self)
                if k == identify_from_k:
                    observer.phase(Phase.IDENTIFY)
            if stop_rule is not None and k in stop_rule.check_ticks:
                # the rule spreads its work over many ticks; its longest call is in the record's timing
                began = time.perf_counter()
                decision = stop_rule.check(k, trace.columns)
                outcome.stop_check_max_s = max(outcome.stop_check_max_s, time.perf_counter() - began)
                if decision is not None:
                    outcome.stop = decision
                    return
            k += 1
