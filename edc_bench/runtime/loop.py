"""The bench loop: the clock-and-bus shell around the tick engine.

Phases: wait for the rig's READY heartbeat (re-arming a latched FAULT with
SAFE), a SAFE command to synchronise the counter and read the rack's start
position, then one RUN command per tick. Every way out, normal or not, ends
with SAFE commands.

What happens at a tick (reply matching, the controller step, the command,
the trace row, the abort checks, the stop rule) is
:class:`~edc_bench.engine.tick.TickEngine`'s, which touches neither bus nor
clock; replay drives the same engine from a CAN log. This shell waits for
each deadline, reads the bus for the time left until the next one (at most
``max_frames_per_tick`` frames: more is a flooded bus), sends what the
engine returns, and logs every frame. The ticks are pipelined
(firmware_proto/PROTOCOL.md, "Timing"): a command goes out on its tick
whatever the replies do. A host stall that costs whole periods is a gap:
the lost ticks are marked in the trace and skipped, never sent late in a
burst.

Per tick little is allocated beyond what python-can and the codec must (the
estimator's two five-element vectors, the typed command; the garbage collector is off during
the loop): the trace and the frame log are preallocated arrays.
"""

from __future__ import annotations

import enum
import gc
import math
import time
import traceback
from collections.abc import Callable
from typing import TYPE_CHECKING, Protocol

from edc_bench.canlib import can
from edc_bench.config.models import Variant
from edc_bench.control.fel import FelController
from edc_bench.engine.abort_figures import BusFloodedFigures, ErrorFigures, RigNotReadyFigures
from edc_bench.engine.commands import BenchCommand
from edc_bench.engine.outcome import Abort, AbortKind, LoopOutcome, StopDecision
from edc_bench.engine.tick import StopRule, TickEngine
from edc_bench.engine.trace import CanFrameLog, Trace, frame_flags
from edc_bench.protocol import BENCH_CMD_ID, Icd, RigFeedback, RigState
from edc_bench.runtime.adapter_counts import adapter_counts
from edc_bench.runtime.clock import Clock, cpu_steal_s
from edc_bench.runtime.stop_worker import StopWorker

if TYPE_CHECKING:
    from can import BusABC


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


class LoopObserver(Protocol):
    """Watches a test as it runs (the live view, log lines). Must return quickly: it runs inside the loop."""

    def phase(self, name: Phase) -> None:
        """The test entered phase ``name`` (:class:`Phase`; ``classify`` comes from
        :func:`~edc_bench.bench.run_bench_test`)."""

    def tick(self, k: int, loop: BenchLoop) -> None:
        """Tick ``k`` has been recorded (every :data:`OBSERVE_EVERY` ticks); read ``loop.trace``, ``loop.outcome``."""


class _AbortTest(Exception):
    """Something that ends the test at once; carries its :class:`~edc_bench.engine.outcome.Abort`."""

    def __init__(self, abort: Abort) -> None:
        super().__init__(abort.sentence)
        self.abort = abort


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

    def __init__(self, bus: BusABC, clock: Clock, variant: Variant, icd: Icd,
                 observer: LoopObserver | None = None, stop_requested: Callable[[], bool] | None = None,
                 stop_rule: StopRule | None = None) -> None:
        self.bus = bus
        self.clock = clock
        self.variant = variant
        self.observer = observer
        self.stop_requested = stop_requested or (lambda: False)
        self.period_s = variant.controller.period_s
        self.ticks = int(round(variant.excitation.duration_s / self.period_s))
        self.engine = TickEngine(variant, icd, self.ticks, stop_rule, timer=time.perf_counter)
        # what the loop can read at most: the frame budget at each of a tick's two reads and each wait step for
        # READY, its own command per tick, the safe stop; a busy or hostile bus is logged whole (the arrays take
        # memory only as frames fill them)
        budget = variant.acceptance.max_frames_per_tick
        ready_steps = int(variant.acceptance.ready_timeout_s / _READY_STEP_S) + 2
        self.frames = CanFrameLog((2 * budget + 1) * self.ticks + (budget + 1) * (ready_steps + 10) + 4096)
        self.max_frames_per_tick = budget
        self._t_s = 0.0
        self._sent_any = False
        # real time: the stop rule's calls run beside the ticks (runtime.stop_worker); simulated time: inside them
        self._stop_worker = StopWorker(self.engine) if stop_rule is not None and clock.waits_for_replies else None

    # what observers and callers read: the engine's
    @property
    def trace(self) -> Trace:
        """The test's trace."""
        return self.engine.trace

    @property
    def outcome(self) -> LoopOutcome:
        """What happened so far."""
        return self.engine.outcome

    @property
    def controller(self) -> FelController | None:
        """The controller (None before the ticks began)."""
        return self.engine.controller

    @property
    def stop_rule(self) -> StopRule | None:
        """The early stop, if any."""
        return self.engine.stop_rule

    # -- frames ----------------------------------------------------------------
    def _send(self, command: BenchCommand) -> BenchCommand:
        """Send ``command`` and log it; returns it (to await its reply)."""
        data = command.payload
        self._sent_any = True
        self.bus.send(can.Message(arbitration_id=BENCH_CMD_ID, data=data, is_extended_id=False))
        self.frames.add(self.clock.now_s() if self.clock.waits_for_replies else self._t_s, BENCH_CMD_ID, data, False)
        self.clock.after_send(self._t_s)
        return command

    def _read(self, until_s: float, replies_expected: bool = True) -> tuple[bool, RigFeedback | None]:
        """Read the next frame, waiting at most until ``until_s`` (never, in lockstep), log it and hand it to the
        engine: whether a frame came, and the reply it held, if any."""
        clock = self.clock
        if clock.waits_for_replies:
            timeout = until_s - clock.now_s()
            msg = self.bus.recv(timeout) if timeout > 0.0 else self.bus.recv(0.0)
            now = clock.now_s()
        else:
            msg, now = self.bus.recv(0.0), self._t_s
        if msg is None:
            return False, None
        self.frames.add(now, msg.arbitration_id, msg.data, True, frame_flags(msg), msg.dlc)
        return True, self.engine.receive(msg.arbitration_id, msg.data, now, is_rx=msg.is_rx,
                                         other=msg.is_extended_id or msg.is_remote_frame or msg.is_error_frame,
                                         replies_expected=replies_expected)

    def _receive(self, command: BenchCommand | None, deadline_s: float = -math.inf) -> RigFeedback | None:
        """Outside the ticks: read until the reply to ``command`` or its :attr:`~BenchCommand.reply_by_s` (none: only
        heartbeats are wanted, until ``deadline_s``), at most a tick's frame budget of frames."""
        if command is not None:
            deadline_s = command.reply_by_s
        frames = 0
        while frames < self.max_frames_per_tick:
            came, reply = self._read(deadline_s, replies_expected=command is not None)
            if not came:
                if command is None or self.clock.waits_for_replies or self._t_s >= deadline_s:
                    return None
                # simulated time: let it pass in small steps, so a reply on its way through an adapter arrives
                self._t_s = min(deadline_s, self._t_s + 0.25 * self.period_s)
                self.clock.wait_until(self._t_s)
                continue
            frames += 1
            if command is not None and command.is_reply(reply):
                return reply
        self.outcome.events.append(f"more than {self.max_frames_per_tick} frames while waiting for a reply")
        return None

    def _drain(self, until_s: float) -> None:
        """Between ticks: hand the engine what comes until ``until_s``.

        Raises
        ------
        _AbortTest
            More than the frame budget arrived within one tick, or another host sent BENCH_CMD.
        """
        engine = self.engine
        for _ in range(self.max_frames_per_tick):
            came, _ = self._read(until_s)
            if not came:
                return
            if engine.foreign_command:
                raise _AbortTest(Abort(AbortKind.FOREIGN_COMMAND))
        raise _AbortTest(Abort(AbortKind.BUS_FLOODED, BusFloodedFigures(limit=self.max_frames_per_tick)))

    # -- phases ----------------------------------------------------------------
    def _wait_ready(self) -> bool:
        """Wait for READY, re-arming a FAULT with SAFE. False on timeout."""
        step = _READY_STEP_S
        limit = self.variant.acceptance.ready_timeout_s
        rearmed = False
        engine = self.engine
        while self._t_s < limit:
            if self.stop_requested():
                raise KeyboardInterrupt
            self._t_s += step
            self.clock.wait_until(self._t_s)
            self._receive(None, self._t_s + step * 0.5)
            if engine.foreign_command:
                raise _AbortTest(Abort(AbortKind.FOREIGN_COMMAND))  # never send SAFE into another host's test
            if self.outcome.rig_state_at_start is None and engine.rig_state is not None:
                self.outcome.rig_state_at_start = engine.rig_state.name
            if engine.rig_state is RigState.READY:
                return True
            if engine.rig_state in (RigState.FAULT, RigState.RUNNING) and not rearmed:
                self.outcome.events.append(f"rig was {engine.rig_state.name} at start: sent SAFE to re-arm")
                self._receive(self._send(engine.safe_command(self._t_s, step * 0.5)))
                rearmed = True
        return False

    def _safe_stop(self) -> None:
        """Send SAFE until the rig confirms its amplifier is off (up to 5 tries)."""
        engine = self.engine
        for _ in range(5):
            self._t_s = max(self._t_s + self.period_s, self.clock.now_s())
            self.clock.wait_until(self._t_s)
            reply = self._receive(self._send(engine.safe_command(self._t_s, 0.02)))
            if reply is not None and not reply.amp_enabled:
                self.outcome.safe_confirmed = True
                return

    def _phase(self, name: Phase) -> None:
        if self.observer is not None:
            self.observer.phase(name)

    def run(self) -> LoopOutcome:
        """Run the test; always ends with SAFE. Returns what happened."""
        gc_was_enabled = gc.isenabled()
        # what the last test left is young: collect those generations only (a full collection scans everything the
        # process holds, a tenth of a short simulated test); the old generation is collected as Python schedules it,
        # between tests, once the collector is enabled again
        gc.collect(1)
        gc.freeze()  # objects alive now are never scanned again
        gc.disable()  # and no collection interrupts a tick
        self.clock.start()
        outcome = self.outcome
        self.frames.origin_unix_s = outcome.clock_origin_unix_s = time.time() - self.clock.now_s()
        steal_at_start = cpu_steal_s()
        worker = self._stop_worker
        try:
            if worker is not None:
                worker.start()
            outcome.abort = self._run_phases()
        except _AbortTest as stop:
            outcome.abort = stop.abort
        except KeyboardInterrupt:
            outcome.abort = Abort(AbortKind.INTERRUPTED)
        except can.CanError as exc:
            outcome.abort = Abort(AbortKind.BUS_ERROR, ErrorFigures(error=f"{type(exc).__name__}: {exc}"))
        except Exception as exc:  # noqa: BLE001 - a bug must not cost the rig's safety or the data
            outcome.abort = Abort(AbortKind.INTERNAL_ERROR, ErrorFigures(error=f"{type(exc).__name__}: {exc}"))
            outcome.events.append(traceback.format_exc())
        finally:
            self.engine.finish()
            if worker is not None and (outcome.abort is not None or outcome.stop is not None):
                worker.cancel()  # ended otherwise: no decision after it; the call under way ends as the rig goes safe
            try:
                self._phase(Phase.SAFE_STOP)
                if self._sent_any or outcome.abort is None or outcome.abort.kind is not AbortKind.FOREIGN_COMMAND:
                    self._safe_stop()  # run_bench_test's interrupt guard keeps a second Ctrl-C from skipping it
                else:  # never break into another host's test with a SAFE of ours
                    outcome.events.append("no SAFE sent: this bench never commanded the rig, another host does")
            except can.CanError as exc:
                outcome.events.append(f"SAFE could not be sent: {exc}")
            finally:
                try:
                    if worker is not None:
                        self._last_decision(worker)
                finally:
                    outcome.cpu_steal_s = cpu_steal_s() - steal_at_start
                    outcome.reply_age_ticks = dict(sorted(self.engine.matcher.counts.ages.items()))
                    outcome.replies_too_old = self.engine.matcher.counts.too_old
                    self._note_bus_figures()
                    if gc_was_enabled:
                        gc.enable()
                    gc.unfreeze()
        return outcome

    def _last_decision(self, worker: StopWorker) -> None:
        """The worker's last calls, once the rig is safe: a test whose ticks ran to their end takes a decision made
        for its last tick (the last period's end is the last tick), and a failure of the rule ends the test as one
        inside the tick would (simulated time's record is the same)."""
        outcome = self.outcome
        error = worker.close()
        if error is not None:
            if outcome.abort is None:
                outcome.abort = Abort(AbortKind.INTERNAL_ERROR, ErrorFigures(error=f"{type(error).__name__}: {error}"))
            outcome.events.append("".join(traceback.format_exception(error)))
            return
        made = worker.made()
        if made is not None and outcome.stop is None and outcome.abort is None:
            self.engine.take_stop(made[0], outcome.ticks_run - 1)

    def _run_phases(self) -> Abort | None:
        """Wait for READY, synchronise, run the ticks; the abort that ended them, if any."""
        self._phase(Phase.WAIT_READY)
        if not self._wait_ready():
            state = self.engine.rig_state.name if self.engine.rig_state else "no heartbeat"
            return Abort(AbortKind.RIG_NOT_READY, RigNotReadyFigures(
                timeout_s=self.variant.acceptance.ready_timeout_s, state=state))
        if not self._synchronise():
            return Abort(AbortKind.NO_SYNC_REPLY)
        return self._run_ticks()

    def _note_bus_figures(self) -> None:
        """What the bus driver skipped and the frame log could not hold, for the record."""
        outcome, frames = self.outcome, self.frames
        outcome.frames_dropped = frames.dropped
        if frames.dropped:
            outcome.events.append(f"CAN log full: {frames.dropped} frames after the first {frames.count} were "
                                  "counted but not stored")
        counts = adapter_counts(self.bus)
        outcome.bus_bad_lines = counts.bad_lines
        outcome.bus_bad_line_samples = [repr(line) for line in counts.bad_line_samples]
        outcome.bus_device_errors = counts.device_errors
        if outcome.bus_device_errors and outcome.abort is not None:
            outcome.abort = outcome.abort.with_adapter_refused(outcome.bus_device_errors)

    def _synchronise(self) -> bool:
        """A SAFE command to synchronise the counter and read where the rack is; False if it got no reply."""
        engine, T = self.engine, self.period_s
        self._t_s += T
        self.clock.wait_until(self._t_s)
        # not time-critical: frames queued since connecting may come first
        sync = self._send(engine.safe_command(self._t_s, 0.1))
        first = self._receive(sync)
        if engine.foreign_command:
            raise _AbortTest(Abort(AbortKind.FOREIGN_COMMAND))
        if first is None:
            return False
        engine.start(first, sync.counter, max(self._t_s, self.clock.now_s()) + T, self._t_s)
        # building the controller takes 20-50 ms on a slow PC: in real time tick 0 comes a period after it is built,
        # where it cost a test its first 15-21 ticks, lost as a host stall (simulated time stands still meanwhile)
        engine.delay_start(self.clock.now_s() + T)
        return True

    def _skip_stall(self, k: int, lateness_s: float) -> tuple[int, float]:
        """Tick ``k`` woke ``lateness_s`` late, a period or more: a host stall cost whole periods. Skip them (a gap),
        never send them late in a burst; the tick to run next and its lateness."""
        clock, engine, T = self.clock, self.engine, self.period_s
        # counted from now, not from the wake-up, so the tick after the gap is on time even if the stall went on
        if clock.waits_for_replies:
            lateness_s = max(lateness_s, clock.now_s() - engine.tick_time_s(k))
        lost = min(int(lateness_s // T), self.ticks - k)
        engine.skip(k, lost)
        k += lost
        self._t_s = engine.tick_time_s(k)
        return k, (max(0.0, clock.now_s() - self._t_s) if clock.waits_for_replies else 0.0)

    def _run_ticks(self) -> Abort | None:
        """The ticks, each on its deadline; the abort that ended them, if any (an early stop is no abort)."""
        engine, clock, observer, T = self.engine, self.clock, self.observer, self.period_s
        identify_from_k = int(round((self.variant.excitation.move_s + self.variant.excitation.fade_s) / T))
        # real time: read replies until half a period before the next deadline (a wake-up from the read can be
        # late on a busy host), then the clock spins to it; what arrives meanwhile is read before the next step
        read_margin_s = 0.5 * T
        self._phase(Phase.SOFT_START)
        stop_requested = self.stop_requested
        worker = self._stop_worker
        k = 0
        while k < self.ticks:
            if stop_requested():
                return Abort(AbortKind.INTERRUPTED, time_s=k * T)
            t_k = self._t_s = engine.tick_time_s(k)
            lateness = clock.wait_until(t_k)
            try:
                # what came while waiting for this deadline, handed over before anything else as replay does
                # (the same frames between the same two commands); a sample is used only if young enough at tick k
                self._drain(clock.now_s())
                if lateness >= T:
                    skipped_from = k
                    k, lateness = self._skip_stall(k, lateness)
                    if worker is not None:  # the rule's calls for the lost ticks are made all the same
                        for g in range(skipped_from, k):
                            if engine.stop_rule_calls(g):
                                worker.hand_over(g)  # the tick after a stall has no time to spare
                    if k >= self.ticks:
                        return None
                    t_k = engine.tick_time_s(k)
                if k == 0:
                    self.outcome.first_tick_unix_s = time.time()
                command = engine.command(k)
                sent_s = clock.now_s()
                self._send(command)
                engine.sent(k, sent_s, lateness)
                # real time, a short call of the stop rule to make in this tick: it takes the time the replies are
                # read in (what comes meanwhile is read first thing next tick), so that it ends before the next
                # deadline (a feed takes 0.5 ms, about the time left after the read on a slow PC)
                short_call = (worker is not None and engine.stop_rule_calls(k) and not engine.stop_rule_decides(k)
                              and worker.idle())
                self._drain(clock.now_s() if short_call else t_k + T - read_margin_s)
            except _AbortTest as stop:
                return stop.abort.at(t_k - engine.t_start_s)
            abort = engine.check(k)
            if abort is not None:
                return abort
            if observer is not None:
                if k % OBSERVE_EVERY == 0:
                    observer.tick(k, self)
                if k == identify_from_k:
                    observer.phase(Phase.IDENTIFY)
            if worker is None:
                if engine.stop_check(k) is not None:
                    return None
            else:
                inline_decision = self._stop_rule_call_beside(k, worker, short_call)
                made = worker.decision()  # a decision the worker made, and the tick it was made for
                taken = inline_decision if inline_decision is not None else made[0] if made is not None else None
                if taken is not None:  # the test ends at this tick, after the tick the decision was made for
                    engine.take_stop(taken, k)
                    return None
            k += 1
        return None

    def _stop_rule_call_beside(self, k: int, worker: StopWorker, inline: bool) -> StopDecision | None:
        """Real time: the stop rule's call for tick ``k``: a decision is the worker's to make; a short call is made
        here, inside the tick (``inline``: decided before the tick's reply read, which it replaced, while the worker
        was idle: the worker holding the interpreter through the ticks costs them more than the call). A decision
        made here is returned."""
        engine = self.engine
        if not engine.stop_rule_calls(k):
            return None
        if not inline:
            worker.hand_over(k)  # in order after the calls handed over before it
            return None
        return engine.stop_rule_call(k)


__all__ = ["OBSERVE_EVERY", "BenchLoop", "LoopObserver", "LoopOutcome", "Phase", "StopRule"]
