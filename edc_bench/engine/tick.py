"""The tick as a sans-I/O core: frames and times in, commands and typed aborts out.

:class:`TickEngine` owns, for one test, everything that happens at a tick
except waiting and the bus: reading the rig's frames (heartbeats, replies
matched to their commands by counter, another host's commands), the
controller step, the command's bytes, the trace row, the abort checks and
the stop rule's hook. It never touches a bus or a clock (in the spirit of
h11's ``Connection``), so every driver runs the same sequence:

- :class:`~edc_bench.runtime.loop.BenchLoop` (real or simulated time) reads
  frames from its bus and passes them to :meth:`TickEngine.receive`, sends
  what :meth:`TickEngine.command` returns, and tells :meth:`TickEngine.sent`;
- :func:`~edc_bench.replay.replay_frames` passes a CAN log's frames in the
  order the loop logged them (its own commands through :meth:`TickEngine.logged_command`, which finds the
  synchronising SAFE and the tick of each RUN as the loop numbered them), and compares each command it gets with
  the one logged.

Commands come out as :class:`~edc_bench.engine.commands.BenchCommand` values: the payload, its counter (the reply
it expects), its tick and deadline, and the last time its reply is of use.

One tick, in order::

    receive(...)*          what came since the last tick (replies matched for use from ``next_tick``)
    skip(k, lost)          only after a host stall: the lost ticks, as gap rows
    command(k)             controller step -> a BenchCommand (its payload sent by the driver)
    sent(k, ...)           the command went out: its counter in flight, its trace row
    receive(...)*          what comes until the next deadline
    check(k)               abort checks -> Abort or None
    stop_check(k)          the stop rule, at its ticks -> its decision or None (in real time the loop runs
                           stop_rule_call(k) in a worker and hands a decision back with take_stop)

A call out of this order raises :class:`~edc_bench.engine.order.EngineOrderError` naming what was expected
(:mod:`edc_bench.engine.order`).
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable, Container
from typing import Protocol

from edc_bench.config.models import Variant
from edc_bench.control.design import build_controller
from edc_bench.control.fel import FelController
from edc_bench.engine.abort_figures import (
    AmplifierOffFigures,
    HeartbeatLostFigures,
    RepliesMissingFigures,
    RigFaultFigures,
    RigFaultStateFigures,
    SampleOutOfRangeFigures,
    SilenceFigures,
    SlowLinkFigures,
)
from edc_bench.engine.commands import BenchCommand
from edc_bench.engine.order import EnginePhase, order_error
from edc_bench.engine.outcome import Abort, AbortKind, LoopOutcome, RigFaultFlag, StopDecision
from edc_bench.engine.replies import SYNC_TICK, ReplyMatcher, max_reply_age_ticks, stale_limit_ticks
from edc_bench.engine.trace import Trace
from edc_bench.engine.tracking import OffReferenceRun
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

# flag bits of trace column rig_flags
FLAG_AMP, FLAG_WATCHDOG, FLAG_OVER_CURRENT, FLAG_LVDT, FLAG_TRAVEL = 1, 2, 4, 8, 16

#: The engine's phases as plain ints: compared at every call of the tick, where an IntEnum's lookup is not free
_IDLE, _TICKING, _FINISHED = int(EnginePhase.IDLE), int(EnginePhase.TICKING), int(EnginePhase.FINISHED)

#: The modes this bench sends
_MODES = frozenset(int(mode) for mode in Mode)

#: How many of its own commands the engine remembers, to tell an interface's echo from another host's command.
_OWN_COMMANDS_KEPT = 1024


def reply_flags(reply: RigFeedback) -> int:
    """The reply's status bits as the trace's ``rig_flags`` column stores them."""
    return (reply.amp_enabled * FLAG_AMP | reply.watchdog_tripped * FLAG_WATCHDOG
            | reply.over_current * FLAG_OVER_CURRENT | reply.lvdt_fault * FLAG_LVDT
            | reply.travel_limit * FLAG_TRAVEL)


class StopRule(Protocol):
    """Decides whether a test may end before its full length (:class:`~edc_bench.verdict.early_stop.EarlyStop`)."""

    #: ticks after which :meth:`check` is asked (the ends of whole excitation periods, and steps of work spread
    #: between them), in order
    check_ticks: Container[int]
    #: those of them whose call decides and costs milliseconds (the periods' ends): in real time the loop makes
    #: these calls beside the ticks, in a worker thread, and the short ones inside the tick while the worker is idle
    decision_ticks: Container[int]
    #: when the test is expected to end (trace time, s), for the live view
    expected_end_s: float

    def check(self, k: int, columns: dict) -> StopDecision | None:
        """At tick ``k``: the decision to stop now, or None."""


class TickEngine:
    """One test's ticks, without I/O.

    Parameters
    ----------
    variant : Variant
        The variant as the test runs it.
    icd : Icd
        The compiled ICD.
    ticks : int
        Ticks the test may run (the trace's rows).
    stop_rule : StopRule, optional
        Asked at its ticks whether the test may end now.
    timer : callable, optional
        A monotonic clock in seconds, only to measure the stop rule's longest call for the record.
    """

    def __init__(self, variant: Variant, icd: Icd, ticks: int, stop_rule: StopRule | None = None,
                 timer: Callable[[], float] | None = None) -> None:
        self.variant = variant
        self.icd = icd
        self.ticks = ticks
        self.period_s = variant.controller.period_s
        self.stop_rule = stop_rule
        self._timer = timer
        self.trace = Trace(ticks)
        self.outcome = LoopOutcome(ticks_planned=ticks)
        self.matcher = ReplyMatcher(max_reply_age_ticks(variant))
        self.controller: FelController | None = None
        self.counter = 0  # the last command's counter
        self.run_base = 0  # tick k's command carries counter run_base + k
        self.next_tick = 0  # the tick a reply arriving now could first be used at
        self.t_start_s = 0.0
        self.rig_state: RigState | None = None
        self.rig_fault_code = 0
        self.last_heartbeat_s = 0.0
        self.position_mm = math.nan
        self.current_a = math.nan
        self.newest_reply: RigFeedback | None = None
        self.newest_flags = 0  # its status bits as the trace stores them
        self.drive_v = math.nan  # the last command's drive
        self.foreign_command = False  # another host's BENCH_CMD was seen
        self.ticking = False  # between start() and finish(): replies are matched to the ticks' commands
        self.phase = _IDLE
        self.expected_k = 0  # the next tick to command (or skip)
        self.commanded_k = -1  # the tick whose command was made and is not yet marked sent (-1: none)
        self.safe_counter: int | None = None  # the last SAFE's counter before the ticks: the one that synchronises
        self.sync_reply: RigFeedback | None = None  # the reply to it, once read
        self._reply_age_ticks = max_reply_age_ticks(variant)
        self._sent_s = [0.0] * ticks
        self._own: deque[bytes] = deque(maxlen=_OWN_COMMANDS_KEPT)
        self._limits()

    def _limits(self) -> None:
        variant, acceptance, T = self.variant, self.variant.acceptance, self.period_s
        self._max_in_row = acceptance.max_missed_replies_in_row
        # without a usable sample the PID holds; as long as the rig's watchdog lets a silent bench go (the
        # replies still coming, too late: a link that held them back once), the test goes on
        self._max_stale_in_row = stale_limit_ticks(variant)
        self._heartbeat_timeout_s = variant.rig.heartbeat_period_ms * 1e-3 * acceptance.heartbeat_timeout_periods
        self._off_reference = OffReferenceRun(acceptance.max_tracking_error_mm, acceptance.tracking_error_ticks)
        self._follow_from_k = int(variant.excitation.move_s / T)  # the rack must follow once it has arrived
        self._position_range = (variant.rig.travel_min_mm - 1.0, variant.rack.stroke_mm + 1.0)

    # -- frames in -------------------------------------------------------------------------------------------
    def receive(self, can_id: int, data: bytes | bytearray, now_s: float, *, other: bool = False,
                is_rx: bool = True, replies_expected: bool = True) -> RigFeedback | None:
        """Take one frame read from the bus at ``now_s``.

        Parameters
        ----------
        can_id, data
            The frame's identifier and payload.
        now_s : float
            When it was read (clock time; NaN where unknown, as in replay).
        other : bool
            An extended, remote or error frame: no ICD message.
        is_rx : bool
            False for an interface's echo of a frame this bench sent.
        replies_expected : bool
            False while the bench waits for READY and has sent nothing: a reply then is no one's, and not read.

        Returns
        -------
        RigFeedback or None
            A reply with a valid CRC (matched to its command while the ticks run), else None.
        """
        outcome = self.outcome
        if other:
            outcome.other_frames += 1
            return None
        if can_id == RIG_FEEDBACK_ID:
            if not replies_expected:
                return None
            try:
                reply = self.icd.parse_rig_feedback(data)
            except ProtocolError:
                outcome.bad_replies += 1
                return None
            if self.ticking:
                self._match(reply, now_s)
            elif self.phase == _IDLE and reply.counter == self.safe_counter:
                self.sync_reply = reply  # the reply the ticks start from (the loop's or a log's last SAFE)
            return reply
        if can_id == RIG_HEARTBEAT_ID:
            self._heartbeat(data, now_s)
        elif can_id == BENCH_CMD_ID:
            if self._is_foreign_command(data, is_rx):
                outcome.other_frames += 1
                self.foreign_command = True
        else:
            outcome.other_frames += 1
        return None

    def _match(self, reply: RigFeedback, now_s: float) -> None:
        """A reply during the ticks: its sample goes into its tick's row and the controller, if still usable."""
        matcher = self.matcher
        tick = matcher.match(reply.counter, self.next_tick)
        if tick is None:
            return
        flags = reply_flags(reply)
        self.trace.reply_arrived(tick, now_s - self._sent_s[tick], reply.position_mm, reply.current_a, flags)
        self._controller().add_sample(tick, reply.position_mm, reply.current_a)
        if tick == matcher.newest_tick:
            self.position_mm, self.current_a, self.newest_reply = reply.position_mm, reply.current_a, reply
            self.newest_flags = flags

    def _heartbeat(self, data: bytes | bytearray, now_s: float) -> None:
        try:
            beat = self.icd.parse_heartbeat(data)
        except ProtocolError:
            return
        outcome = self.outcome
        outcome.heartbeats += 1
        self.rig_state = beat.state
        self.rig_fault_code = beat.fault_code
        self.last_heartbeat_s = now_s
        if outcome.fw_version is None:
            outcome.fw_version = f"{beat.fw_major}.{beat.fw_minor}"

    def _is_foreign_command(self, data: bytes | bytearray, is_rx: bool) -> bool:
        """A valid BENCH_CMD this bench did not send (an interface echoing our own frames is no host).

        Only a command the rig would obey counts (its CRC checked): a damaged frame with the id is no second host.
        """
        if not is_rx:  # python-can marks an interface's echo of our own frame (receive_own_messages)
            return False
        try:
            self.icd.parse_bench_cmd(data)
        except ProtocolError:
            return False
        return bytes(data) not in self._own  # rare: searched only when a command comes in

    # -- commands out ----------------------------------------------------------------------------------------
    def safe_command(self, now_s: float = math.nan, reply_within_s: float = math.nan) -> BenchCommand:
        """A SAFE command with the next counter (outside the ticks).

        Parameters
        ----------
        now_s : float, optional
            Clock time it is made (its :attr:`~BenchCommand.deadline_s`).
        reply_within_s : float, optional
            How long the driver waits for its reply (:attr:`~BenchCommand.reply_by_s` is ``now_s`` plus this).

        Before the ticks, the last SAFE is the one that synchronises: its reply, when :meth:`receive` reads it, is
        :attr:`sync_reply`.
        """
        self.counter = counter = (self.counter + 1) & 0xFF
        if self.phase == _IDLE:
            self.safe_counter, self.sync_reply = counter, None
        return BenchCommand(self._encode(Mode.SAFE, 0.0, 0.0), counter, Mode.SAFE, 0.0, 0.0, None, now_s,
                            now_s + reply_within_s)

    def logged_command(self, data: bytes | bytearray) -> BenchCommand | None:
        """A command this bench sent, read back from its CAN log (replay), as :meth:`safe_command` and
        :meth:`command` made it: a SAFE before the ticks becomes the synchronising one; a RUN gets the tick the loop
        numbered it by (its counter counted from the synchronising SAFE's; a jump is ticks a host stall cost).
        None for a payload that is no valid command (its CRC, or a mode the bench never sends), and for a RUN with no
        SAFE before it.
        """
        try:
            cmd = self.icd.parse_bench_cmd(data)
        except ProtocolError:
            return None
        if cmd.mode not in _MODES:  # a mode this bench never sends (the field has 8 bits): not its command
            return None
        if cmd.mode != Mode.RUN:
            if self.phase == _IDLE:
                self.safe_counter, self.sync_reply = cmd.counter, None
            return BenchCommand(bytes(data), cmd.counter, Mode(cmd.mode), cmd.drive_v, cmd.reference_mm, None,
                                math.nan, math.nan)
        if self.phase == _IDLE:
            if self.safe_counter is None:
                return None
            tick = (cmd.counter - self.safe_counter - 1) & 0xFF
        else:
            k = self.expected_k
            tick = k + ((cmd.counter - self.run_base - k) & 0xFF)
        return BenchCommand(bytes(data), cmd.counter, Mode.RUN, cmd.drive_v, cmd.reference_mm, tick, math.nan,
                            math.nan)

    def _encode(self, mode: int, drive_v: float, reference_mm: float) -> bytes:
        data = self.icd.make_bench_cmd(self.counter, mode, drive_v, min(max(reference_mm, 0.0), 65.535))
        self._own.append(data)
        return data

    def start(self, sync: RigFeedback, sync_counter: int, t_start_s: float, sync_s: float = 0.0) -> None:
        """Begin the ticks from the reply to the synchronising SAFE command (counter ``sync_counter``, sent at
        clock time ``sync_s``).

        Tick k's command carries counter ``sync_counter + 1 + k`` and runs at ``t_start_s + k T``.
        """
        if self.phase != _IDLE:
            raise order_error("start()", self.phase, self.expected_k, self.commanded_k)
        self.position_mm, self.current_a = sync.position_mm, sync.current_a
        self.run_base = (sync_counter + 1) & 0xFF
        self.controller = build_controller(self.variant, sync.position_mm)
        self.controller.add_sample(SYNC_TICK, sync.position_mm)
        self.t_start_s = t_start_s
        self.outcome.ticks_start_s = t_start_s
        self.last_heartbeat_s = max(self.last_heartbeat_s, sync_s)
        self.ticking = True
        self.phase = _TICKING

    def delay_start(self, t_start_s: float) -> None:
        """Tick 0 runs no earlier than ``t_start_s`` (clock time): a driver whose clock ran on while :meth:`start`
        built the controller moves the ticks after it, instead of losing their first ones."""
        if self.phase != _TICKING or self.expected_k != 0 or self.commanded_k >= 0:
            raise order_error("delay_start()", self.phase, self.expected_k, self.commanded_k)
        if t_start_s > self.t_start_s:
            self.t_start_s = self.outcome.ticks_start_s = t_start_s

    def finish(self) -> None:
        """The ticks are over: replies that still come (during the safe stop) are no longer the test's. Legal at
        any time (a test may end before its ticks start, or inside a tick)."""
        self.ticking = False
        self.phase = _FINISHED

    def _controller(self) -> FelController:
        """The controller, once :meth:`start` built it."""
        if self.controller is None:
            raise RuntimeError("the ticks have not started: TickEngine.start() builds the controller")
        return self.controller

    def tick_time_s(self, k: int) -> float:
        """Clock time of tick ``k``'s deadline."""
        return self.t_start_s + k * self.period_s

    def skip(self, k: int, lost: int) -> None:
        """A host stall cost ticks ``k`` to ``k + lost - 1``: gap rows for them, and the controller resynchronised.

        Skipped, never sent late in a burst.
        """
        if self.phase != _TICKING or self.commanded_k >= 0 or k != self.expected_k or lost < 1:
            raise order_error(f"skip({k}, {lost})", self.phase, self.expected_k, self.commanded_k)
        self.expected_k = k + lost
        trace, ctl, t0 = self.trace, self._controller(), self.t_start_s
        for g in range(k, k + lost):
            trace.write_gap(g, self.tick_time_s(g) - t0, ctl)
        self.outcome.gaps += 1
        self.outcome.ticks_lost += lost
        if k + lost < self.ticks:
            ctl.resync()
        else:
            self.outcome.ticks_run = self.ticks

    def command(self, k: int) -> BenchCommand:
        """The controller's step for tick ``k``: the RUN command (its drive also in :attr:`drive_v`)."""
        if self.phase != _TICKING or self.commanded_k >= 0 or k != self.expected_k:
            raise order_error(f"command({k})", self.phase, self.expected_k, self.commanded_k)
        self.commanded_k = k
        ctl = self._controller()
        self.drive_v = drive_v = ctl.step(k, newest_usable=self.matcher.usable(k))
        self.counter = counter = (self.run_base + k) & 0xFF
        reference_mm = min(max(ctl.reference_mm, 0.0), 65.535)
        deadline_s = self.t_start_s + k * self.period_s
        return BenchCommand(self._encode(Mode.RUN, drive_v, reference_mm), counter, Mode.RUN, drive_v, reference_mm,
                            k, deadline_s, deadline_s + self._reply_age_ticks * self.period_s)

    def sent(self, k: int, sent_s: float, lateness_s: float) -> None:
        """Tick ``k``'s command went out at ``sent_s`` (clock time), ``lateness_s`` after its deadline."""
        if self.phase != _TICKING or k != self.commanded_k:
            raise order_error(f"sent({k})", self.phase, self.expected_k, self.commanded_k)
        self.commanded_k = -1
        self.expected_k = k + 1
        matcher = self.matcher
        self._sent_s[k] = sent_s
        matcher.sent(k, self.counter)
        self.trace.write_tick(k, self.tick_time_s(k) - self.t_start_s, lateness_s, math.nan, self._controller(),
                              self.position_mm, self.current_a, self.drive_v, False, self.newest_flags,
                              k - matcher.newest_tick)
        outcome = self.outcome
        outcome.ticks_run = k + 1
        if lateness_s > self.period_s:
            outcome.ticks_late += 1
        self.next_tick = k + 1

    # -- decisions -------------------------------------------------------------------------------------------
    def _after_tick(self, method: str, k: int) -> None:
        """A call that belongs after tick ``k`` was run (commanded and sent) and before the next."""
        if self.phase != _TICKING or self.commanded_k >= 0 or k != self.expected_k - 1:
            raise order_error(f"{method}({k})", self.phase, self.expected_k, self.commanded_k)

    def check(self, k: int) -> Abort | None:
        """After tick ``k``'s reads: the abort that ends the test now, or None."""
        self._after_tick("check", k)  # the call's words made only for an error: this runs every tick
        outcome, counts = self.outcome, self.matcher.counts
        outcome.missed_replies = counts.missed
        outcome.max_missed_in_row = counts.max_missed_in_row
        outcome.max_unanswered_in_row = counts.max_unanswered_in_row
        abort = self._abort(k)
        if abort is None and k > self._follow_from_k and self._off_reference.update(
                self._controller().reference_mm, self.position_mm):
            abort = Abort(AbortKind.OFF_REFERENCE, self._off_reference.figures())
        return None if abort is None else abort.at(self.tick_time_s(k) - self.t_start_s)

    def _abort(self, k: int) -> Abort | None:
        """The rig's and the link's checks, in the order they are asked."""
        reply, counts, acceptance = self.newest_reply, self.matcher.counts, self.variant.acceptance
        if reply is not None and reply.any_fault:
            flags = tuple(str(flag) for flag, bit in ((RigFaultFlag.WATCHDOG_TRIPPED, reply.watchdog_tripped),
                                                      (RigFaultFlag.OVER_CURRENT, reply.over_current),
                                                      (RigFaultFlag.LVDT_FAULT, reply.lvdt_fault),
                                                      (RigFaultFlag.TRAVEL_LIMIT, reply.travel_limit)) if bit)
            return Abort(AbortKind.RIG_FAULT, RigFaultFigures(flags=flags))
        if reply is not None and not reply.amp_enabled:
            return Abort(AbortKind.AMPLIFIER_OFF, AmplifierOffFigures(
                state=self.rig_state.name if self.rig_state else "unknown",
                fault_code=FaultCode(self.rig_fault_code).name))
        if counts.unanswered_in_row > self._max_in_row:
            return Abort(AbortKind.SILENCE, SilenceFigures(
                in_row=counts.unanswered_in_row, limit=self._max_in_row, bad_replies=self.outcome.bad_replies,
                too_old=counts.too_old))
        if counts.missed_in_row > self._max_stale_in_row:
            return Abort(AbortKind.SLOW_LINK, SlowLinkFigures(
                in_row=counts.missed_in_row, limit=self._max_stale_in_row, too_old=counts.too_old,
                limit_from_watchdog=self._max_stale_in_row > self._max_in_row,
                max_reply_age_ms=acceptance.max_reply_age_ms))
        # the limit is of the whole test: end it once it can no longer be kept. A running fraction ended tests
        # through a USB adapter in their first second (3 host stalls of 3 ms: 12 of 1,177 replies too old)
        if counts.missed > acceptance.max_missed_reply_fraction * self.ticks:
            return Abort(AbortKind.REPLIES_MISSING, RepliesMissingFigures(
                missed=counts.missed, ticks=k + 1, limit_fraction=acceptance.max_missed_reply_fraction,
                planned=self.ticks))
        silent_s = self.tick_time_s(k) - self.last_heartbeat_s
        if silent_s > self._heartbeat_timeout_s:
            return Abort(AbortKind.HEARTBEAT_LOST, HeartbeatLostFigures(
                silent_ms=silent_s * 1e3, limit_ms=self._heartbeat_timeout_s * 1e3))
        if self.rig_state is RigState.FAULT:
            return Abort(AbortKind.RIG_FAULT_STATE,
                         RigFaultStateFigures(fault_code=FaultCode(self.rig_fault_code).name))
        low, high = self._position_range
        over_current_a = self.variant.rig.over_current_a
        if not (low <= self.position_mm <= high) or abs(self.current_a) > over_current_a:
            return Abort(AbortKind.SAMPLE_OUT_OF_RANGE, SampleOutOfRangeFigures(
                position_mm=self.position_mm, current_a=self.current_a, position_min_mm=low, position_max_mm=high,
                current_max_a=over_current_a))
        return None

    def stop_check(self, k: int) -> StopDecision | None:
        """At tick ``k``: the stop rule's decision to end the test now, if it has one (kept in the outcome)."""
        self._after_tick("stop_check", k)
        decision = self.stop_rule_call(k)
        if decision is not None:
            self.take_stop(decision, k)
        return decision

    def stop_rule_call(self, k: int) -> StopDecision | None:
        """The stop rule's call for tick ``k`` (None at a tick that is not one of its ``check_ticks``), timed.

        It reads only the trace and the rule's own state, so a driver may run it beside the ticks, in another
        thread (the real-time loop does: its decision costs milliseconds on a slow PC); the driver then hands the
        decision back with :meth:`take_stop`.
        """
        rule = self.stop_rule
        if rule is None or k not in rule.check_ticks:
            return None
        # the rule spreads its work over many ticks; its longest call is in the record's timing
        timer = self._timer
        began = timer() if timer is not None else 0.0
        decision = rule.check(k, self.trace.columns)
        if timer is not None:
            self.outcome.stop_check_max_s = max(self.outcome.stop_check_max_s, timer() - began)
        return decision

    def stop_rule_calls(self, k: int) -> bool:
        """True when the stop rule has a call at tick ``k`` (one of its ``check_ticks``)."""
        rule = self.stop_rule
        return rule is not None and k in rule.check_ticks

    def stop_rule_decides(self, k: int) -> bool:
        """True when the stop rule's call for tick ``k`` is a decision (long: see :class:`StopRule`)."""
        rule = self.stop_rule
        return rule is not None and k in rule.decision_ticks

    def take_stop(self, decision: StopDecision, k: int) -> None:
        """The test ends at tick ``k`` on the stop rule's ``decision`` (made at its ``time_s``, a period's end):
        kept in the outcome with ``decided_s``, the trace time at the end of that tick (``time_s`` when taken
        inside the tick, as in simulated time)."""
        if self.phase == _IDLE or not 0 <= k < self.expected_k:
            raise order_error(f"take_stop(..., {k})", self.phase, self.expected_k, self.commanded_k)
        self.outcome.stop = decision.with_decided(self.tick_time_s(k + 1) - self.t_start_s)


__all__ = ["StopRule", "TickEngine", "reply_flags"]
