"""Run a bench test from Python: the API a test engineer scripts against.

Example
-------
On the simulated rig, in simulated time::

    from edc_bench.bench import run_simulated_test
    from edc_bench.config import load_variant

    result = run_simulated_test(load_variant("p-edc-default"), valve="worn", seed=3)
    print(result.verdict, result.features, result.truth)

On any python-can bus (a real rig, or ``edc-bench rig`` over slcan)::

    import can
    from edc_bench.bench import BenchOptions, run_bench_test
    from edc_bench.config import load_variant
    from edc_bench.runtime.clock import RealTimeClock

    with can.Bus(interface="slcan", channel="socket://127.0.0.1:5000", bitrate=500000,
                 sleep_after_open=0) as bus:
        result = run_bench_test(bus, RealTimeClock(), load_variant(), BenchOptions(valve_id="V-0042"))
"""

from __future__ import annotations

import contextlib
import dataclasses
import datetime as _dt
import itertools
import uuid
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from edc_bench.canlib import can

from edc_bench.config.models import Variant
from edc_bench.physics.feedforward import FeedforwardParameters
from edc_bench.physics.valve import ValveSpec, parse_valve_spec
from edc_bench.verdict.baseline import Baseline, load_baseline
from edc_bench.verdict.judgement import judge_run

if TYPE_CHECKING:
    from edc_bench.sim.adapter import AdapterModel
    from edc_bench.sim.drift import SensorDrift
    from edc_bench.sim.pump_faults import RackFault, SensorFault
    from edc_bench.sim.rig import SimulatedRig
    from edc_bench.records.simulation import SimulationSummary
from edc_bench.engine.outcome import LoopOutcome, StopReason
from edc_bench.protocol import Icd, default_icd
from edc_bench.records.record import BenchResult
from edc_bench.records.schema import Identity, StabilityMargins, StopSummary
from edc_bench.records.stream import StreamingCanLog
from edc_bench.runtime.clock import Clock, SimulatedClock
from edc_bench.runtime.clock_kind import ClockKind
from edc_bench.runtime.gain_check import check_variant_gains
from edc_bench.runtime.loop import BenchLoop, LoopObserver, Phase, StopRule
from edc_bench.runtime.priority import realtime_priority
from edc_bench.runtime.signals import interrupt_guard, stop_requested
from edc_bench.engine.tick_timing import TickTiming
from edc_bench.runtime.timing import timing_summary

__all__ = ["BenchResult", "BenchOptions", "run_bench_test", "run_simulated_test"]


@dataclass(frozen=True)
class BenchOptions:
    """How to run one bench test: everything but the bus, the clock and the variant, in one typed value.

    Attributes
    ----------
    valve_id : str
        Identity of the valve under test, for the record.
    identity : Identity
        Who and where (``pump_serial``, ``station``, ``operator``, the workshop, ``job_ref``), for the record and the
        history.
    classify : bool
        Judge a trustworthy test with the classifier (default); off for baseline calibration.
    classifier_path : pathlib.Path or None
        ONNX model to judge with; by default the one the variant's valves are judged by (its own, if its file names
        one; else the station's: adopted, else packaged).
    check_gains : bool
        Check the PID gains' margins with python-control first (default).
    coil_temp_c : float or None
        The coil's temperature at the start, to refer its measured resistance to 20 degC (20 degC if not given).
    nominal_baseline : bool
        Judge a variant that has no measured baseline against the nominal one (``--nominal-baseline``);
        by default such a test ends INVALID, "variant not calibrated".
    calibrate_command : str or None
        The command that calibrates the variant on this rig, quoted in that reason.
    full_length : bool
        Run the variant's whole duration; by default a classified test stops as soon as its verdict is certain
        or its model is known not to fit (:mod:`edc_bench.verdict.early_stop`).
    observer : LoopObserver or None
        Told the phases and shown the loop as it runs (live view, log lines).
    stream_can_log : callable or None
        Given the test's start (UTC, ISO 8601, the record's ``started_at``), returns the file to stream the raw CAN
        log to while the test runs (called once the test is about to start), so that a killed process leaves a
        readable log.
    truth : FeedforwardParameters or None
        True parameters, when the rig is simulated.
    describe_rig : callable or None
        Called once the loop has ended: what the record says of a simulated rig (``simulation``).
    icd : Icd or None
        Compiled ICD (the packaged one by default).
    rig_on_this_pc : bool
        The rig is a process on this PC (the simulated rig process, a loopback socket, a pseudo-terminal): a link's
        abort then points at the PC, not a cable (the record's ``timing.rig_on_this_pc``).
    """

    valve_id: str = ""
    identity: Identity = Identity()
    classify: bool = True
    classifier_path: Path | None = None
    check_gains: bool = True
    coil_temp_c: float | None = None
    nominal_baseline: bool = False
    calibrate_command: str | None = None
    full_length: bool = False
    observer: LoopObserver | None = None
    stream_can_log: Callable[[str], Path] | None = None
    truth: FeedforwardParameters | None = None
    describe_rig: Callable[[], SimulationSummary] | None = None
    icd: Icd | None = None
    rig_on_this_pc: bool = False


def run_bench_test(bus: can.BusABC, clock: Clock, variant: Variant, options: BenchOptions | None = None) -> BenchResult:
    """Run one bench test on ``bus``.

    Parameters
    ----------
    bus : can.BusABC
        Bus to the rig (any python-can interface).
    clock : Clock
        :class:`~edc_bench.runtime.clock.SimulatedClock` (lockstep with an
        in-process rig) or :class:`~edc_bench.runtime.clock.RealTimeClock`.
    variant : Variant
        Pump variant.
    options : BenchOptions, optional
        Everything else (the valve's identity, judging, the live view...); the defaults otherwise.

    Returns
    -------
    BenchResult
        Complete, built once: also when the test was aborted (then the verdict is INVALID and the trace holds
        what was measured).

    Raises
    ------
    ConfigError
        If the variant's gains are unstable or marginal on its nominal plant.
    """
    o = options or BenchOptions()
    margins = check_variant_gains(variant) if o.check_gains else None
    # loaded before the test: a damaged baseline file, or a variant's own model that is missing, is refused now, not
    # after it
    baseline = load_baseline(variant) if o.classify else None
    if o.classify and o.classifier_path is None:
        from edc_bench.verdict.classifier import variant_model_path

        variant_model_path(variant)
    started = _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds")
    # the test's own id, fixed at its start: the history knows the test by it wherever its folder is copied
    test_id = uuid.uuid4().hex
    stop_rule = _stop_rule(variant, o, baseline)
    loop = BenchLoop(bus, clock, variant, o.icd or default_icd(), o.observer, stop_requested=stop_requested,
                     stop_rule=stop_rule)
    # in real time the loop runs at a real-time priority where the PC permits (runtime/priority.py)
    # (a wrapped simulated clock, StallingClock, is simulated time too: it waits for no reply)
    with realtime_priority() if clock.waits_for_replies else contextlib.nullcontext() as priority:
        outcome, can_log_path = _run_loop(loop, o.stream_can_log, started)
    trace = loop.trace.view()
    timing = TickTiming(
        **timing_summary(trace, variant.controller.period_s), missed_replies=outcome.missed_replies,
        cpu_steal_s=outcome.cpu_steal_s, first_tick_unix_s=outcome.first_tick_unix_s,
        scheduling=None if priority is None else priority.describe(),
        # the early stop's longest call, which a real-time tick had to wait for
        stop_check_max_us=None if stop_rule is None else outcome.stop_check_max_s * 1e6,
        rig_on_this_pc=o.rig_on_this_pc or None)
    if o.observer is not None:
        o.observer.phase(Phase.CLASSIFY)
    judgement = judge_run(variant, trace, loop.controller, outcome, timing, truth=o.truth, classify=o.classify,
                          classifier_path=o.classifier_path, coil_temp_c=o.coil_temp_c,
                          nominal_baseline=o.nominal_baseline, calibrate_command=o.calibrate_command,
                          baseline=baseline, real_rig=clock.kind is ClockKind.REAL_TIME)
    return BenchResult(
        stop=stop_summary(variant, outcome, o.full_length, stop_rule is not None),
        judgement=judgement,
        timing=timing,
        outcome=outcome,
        margins=None if margins is None else StabilityMargins(**dataclasses.asdict(margins)),
        variant=variant,
        valve_id=o.valve_id,
        started_at=started,
        test_id=test_id,
        clock=str(clock.kind),
        trace=trace,
        frames=loop.frames,
        truth=o.truth,
        can_log_path=can_log_path,
        identity=o.identity,
        simulation=o.describe_rig() if o.describe_rig is not None else None,
    )


def _stop_rule(variant: Variant, o: BenchOptions, baseline: Baseline | None) -> StopRule | None:
    """The early stop, for a classified test against a calibrated (or deliberately nominal) baseline."""
    if not o.classify or o.full_length or baseline is None or not (baseline.calibrated or o.nominal_baseline):
        return None
    from edc_bench.verdict.classifier import default_classifier
    from edc_bench.verdict.early_stop import EarlyStop

    return EarlyStop(variant, baseline,
                     default_classifier(str(o.classifier_path) if o.classifier_path else None, variant))


def _run_loop(loop: BenchLoop, stream_can_log: Callable[[str], Path] | None,
              started_at: str) -> tuple[LoopOutcome, Path | None]:
    """Run the loop, streaming the CAN log where asked (the target is given the test's start, which names its
    folder); the outcome, and where the log was streamed completely."""
    stream = None
    if stream_can_log is not None:
        try:
            stream = StreamingCanLog(loop.frames, stream_can_log(started_at))
        except OSError as exc:  # a full disk, a folder that vanished: the frames stay in memory all the same
            loop.outcome.events.append(f"can.log could not be opened for streaming ({type(exc).__name__}: {exc}); "
                                       "every frame is kept in memory and written with the record")
    # Ctrl-C ends the test as an abort (SAFE); with no caller's guard around this one (perf, rig-selfcheck) it is
    # raised once the loop has ended, so that no one goes on with the cut test as if it were whole
    with interrupt_guard():
        if stream is None:
            return loop.run(), None
        with stream:
            outcome = loop.run()
    if stream.error is not None:
        outcome.events.append(f"can.log could not be streamed during the test ({stream.error}); every frame "
                              "is kept in memory and written with the record")
    return outcome, stream.path if stream.complete else None


def stop_summary(variant: Variant, outcome: LoopOutcome, full_length: bool, early_stop: bool) -> StopSummary:
    """Why and when the test ended, for the record."""
    period_s = variant.controller.period_s
    if outcome.stop is not None:  # the stop rule's decision: its figures under the same names
        stop = StopSummary.model_validate(outcome.stop, from_attributes=True)
    elif outcome.abort is not None:
        stop = StopSummary(reason=StopReason.ABORTED, time_s=outcome.abort_time_s if outcome.abort_time_s is not None
                           else outcome.ticks_run * period_s)
    else:
        stop = StopSummary(reason=StopReason.FULL_LENGTH, time_s=outcome.ticks_run * period_s)
    why_full_length = None
    if stop.reason is StopReason.FULL_LENGTH and not full_length:
        why_full_length = ("no early stop: the test is not classified against a calibrated baseline"
                           if not early_stop else "the verdict was not certain before the maximum duration")
    return stop.model_copy(update={"max_s": variant.excitation.duration_s, "full_length": full_length,
                                   "early_stop": early_stop, "why_full_length": why_full_length})


_channels = itertools.count()


def run_simulated_test(variant: Variant, valve: str | ValveSpec = "new", seed: int = 0, *,
                       stiction: bool = True, sensor_noise: bool = True, adapter: AdapterModel | str | None = None,
                       clock_wrapper: Callable[[Clock], Clock] | None = None, options: BenchOptions | None = None,
                       firmware: str = "python", drift: SensorDrift | str | None = None,
                       rack_fault: RackFault | str | None = None, sensor_fault: SensorFault | str | None = None,
                       **option_fields: Any) -> BenchResult:
    """Run a bench test against the simulated rig in process, in simulated time.

    Parameters
    ----------
    variant : Variant
        Pump variant.
    valve : str or ValveSpec
        ``new``, ``worn``, ``faulty``, physical values (see
        :func:`~edc_bench.physics.valve.parse_valve_spec`) or a spec.
    seed : int
        Seed of the rig's sensor noise.
    stiction, sensor_noise : bool
        Switch the plant's stiction and the sensors' noise off to get the
        plant the identification model assumes.
    adapter : AdapterModel or str, optional
        The CAN adapter's timing between bench and rig (a preset name such as
        ``usb-fs``, see :func:`~edc_bench.sim.adapter.parse_adapter`); instant by default.
    clock_wrapper : callable, optional
        Wraps the simulated clock (e.g. :class:`~edc_bench.testing.stalls.StallingClock` to inject host stalls).
    firmware : str, optional
        The rig's firmware: ``python`` (the prototype) or ``c`` (the C core, :mod:`firmware_proto.c_firmware`).
    drift : SensorDrift or str, optional
        The rig's sensors drifted (``lvdt_offset_mm=0.05``, see :func:`~edc_bench.sim.drift.parse_rig_drift`);
        none by default.
    rack_fault, sensor_fault : RackFault or SensorFault or str, optional
        The pump's control rack binds or drags, its rack-travel sensor misreads (``bind``, ``gain=1.08``: see
        :mod:`edc_bench.sim.pump_faults`); sound by default.
    options : BenchOptions, optional
        As :func:`run_bench_test`; single fields may be given by name instead (``full_length=True``). The
        valve id defaults to the valve's spec; ``coil_temp_c`` is what the technician states, not taken from
        the simulated valve, which the bench does not know.

    Returns
    -------
    BenchResult
        With ``truth`` set to the simulated plant's parameters and ``simulation`` describing the rig.
    """
    from edc_bench.sim.adapter import AdapterModel, parse_adapter
    from edc_bench.sim.drift import SensorDrift, parse_rig_drift
    from edc_bench.sim.pump_faults import RackFault, SensorFault, parse_rack_fault, parse_sensor_fault
    from edc_bench.sim.rig import RigOptions, SimulatedRig

    spec = valve if isinstance(valve, ValveSpec) else parse_valve_spec(valve, variant)
    link = parse_adapter(adapter) if isinstance(adapter, str) else (adapter or AdapterModel())
    sensors = parse_rig_drift(drift) if isinstance(drift, str) else (drift or SensorDrift())
    rack = parse_rack_fault(rack_fault) if isinstance(rack_fault, str) else (rack_fault or RackFault())
    sensor = parse_sensor_fault(sensor_fault) if isinstance(sensor_fault, str) else (sensor_fault or SensorFault())
    rig = SimulatedRig(variant, spec, seed, RigOptions(stiction=stiction, sensor_noise=sensor_noise, firmware=firmware,
                                                       drift=sensors, rack_fault=rack, sensor_fault=sensor))
    o = dataclasses.replace(options or BenchOptions(), **option_fields)
    o = dataclasses.replace(o, valve_id=o.valve_id or spec.label, truth=rig.truth,
                            describe_rig=lambda: _simulation(variant, spec, rig, link, seed, stiction, sensor_noise))
    return run_on_simulated_rig(variant, rig, o, link, seed, clock_wrapper)


def run_on_simulated_rig(variant: Variant, rig: SimulatedRig, options: BenchOptions,
                         adapter: AdapterModel | None = None, seed: int = 0,
                         clock_wrapper: Callable[[Clock], Clock] | None = None) -> BenchResult:
    """Run a bench test against ``rig`` in process, in simulated time (lockstep): the loop, the identification, the
    verdict and the part diagnosis as on any rig.

    :func:`run_simulated_test` builds the project's simulated rig and calls this; a test may build a rig of its own
    (another plant or sensor behind the same firmware) and run the bench on it here.

    Parameters
    ----------
    variant : Variant
    rig : SimulatedRig
    options : BenchOptions
        As :func:`run_bench_test`.
    adapter : AdapterModel, optional
        The CAN adapter's timing (instant by default).
    seed : int, optional
        Seeds the adapter's jitter.
    clock_wrapper : callable, optional
        Wraps the simulated clock.
    """
    from edc_bench.sim.adapter import AdapterModel
    from edc_bench.sim.inprocess import InProcessRig
    from edc_bench.sim.lockstep_bus import lockstep_pair

    link = adapter or AdapterModel()
    bench_bus, rig_bus = lockstep_pair(f"edc-bench-sim-{next(_channels)}")
    with bench_bus, rig_bus:
        clock: Clock = SimulatedClock(InProcessRig(rig_bus, rig, link, seed))
        if clock_wrapper is not None:
            clock = clock_wrapper(clock)
        return run_bench_test(bench_bus, clock, variant, options)


def _simulation(variant: Variant, spec: ValveSpec, rig: SimulatedRig, link: AdapterModel, seed: int,
                stiction: bool, sensor_noise: bool) -> SimulationSummary:
    """What the record says of the simulated rig after a test (the coil has warmed): the valve, its coil, the link
    and the firmware's counters."""
    from edc_bench.physics.wear import is_faulty, resisting_force_n
    from edc_bench.records.simulation import RigCounters, SimulatedCoil, SimulatedValve, SimulationSummary

    params, counters, drift = rig.plant_params, rig.firmware.counters, rig.options.drift
    return SimulationSummary(
        valve=SimulatedValve(label=spec.label, clearance_mm=spec.clearance_mm, roughness=spec.roughness,
                             friction_scale=spec.friction_scale, damping_scale=spec.damping_scale),
        coil=SimulatedCoil(resistance_20c_ohm=params.resistance_20c_ohm, temp_start_c=params.coil_temp_c,
                           temp_end_c=rig.plant.coil_temp_c, resistance_start_ohm=params.resistance_ohm,
                           resistance_end_ohm=rig.plant.resistance_ohm),
        seed=seed, stiction=stiction, sensor_noise=sensor_noise, firmware=rig.options.firmware,
        sensor_drift=None if drift.none else dataclasses.asdict(drift), adapter=dataclasses.asdict(link),
        faulty_by_physics=is_faulty(variant, spec), resisting_force_n=resisting_force_n(variant, spec),
        coulomb_friction_n=params.coulomb_friction_n, damping_n_s_per_mm=params.damping_n_s_per_mm,
        rig_counters=RigCounters(accepted=counters.accepted, bad_crc=counters.bad_crc, bad_mode=counters.bad_mode,
                                 watchdog_trips=counters.watchdog_trips),
        rack_fault=None if rig.options.rack_fault.none else dataclasses.asdict(rig.options.rack_fault),
        sensor_fault=None if rig.options.sensor_fault.none else dataclasses.asdict(rig.options.sensor_fault),
    )
