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
    from edc_bench.bench import run_bench_test
    from edc_bench.runtime.clock import RealTimeClock

    with can.Bus(interface="slcan", channel="socket://127.0.0.1:5000", bitrate=500000,
                 sleep_after_open=0) as bus:
        result = run_bench_test(bus, RealTimeClock(), load_variant(), valve_id="V-0042")
"""

from __future__ import annotations

import dataclasses
import datetime as _dt
import itertools
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

import can

from edc_bench.config.models import Variant
from edc_bench.physics.feedforward import FeedforwardParameters
from edc_bench.physics.valve import ValveSpec, parse_valve_spec
from edc_bench.verdict.baseline import load_baseline
from edc_bench.verdict.judgement import judge_run

if TYPE_CHECKING:
    from edc_bench.sim.adapter import AdapterModel
from edc_bench.engine.outcome import LoopOutcome, StopReason
from edc_bench.protocol import Icd, default_icd
from edc_bench.records.record import BenchResult
from edc_bench.records.stream import StreamingCanLog
from edc_bench.runtime.clock import Clock, SimulatedClock
from edc_bench.runtime.gain_check import check_variant_gains
from edc_bench.runtime.loop import BenchLoop, LoopObserver, Phase
from edc_bench.runtime.signals import interrupt_guard, stop_requested
from edc_bench.runtime.timing import timing_summary

__all__ = ["BenchResult", "run_bench_test", "run_simulated_test"]


def run_bench_test(bus: can.BusABC, clock: Clock, variant: Variant, *, valve_id: str = "",
                   icd: Icd | None = None, observer: LoopObserver | None = None,
                   truth: FeedforwardParameters | None = None, check_gains: bool = True,
                   classify: bool = True, classifier_path: Path | None = None,
                   stream_can_log: Callable[[], Path] | None = None,
                   coil_temp_c: float | None = None, nominal_baseline: bool = False,
                   calibrate_command: str | None = None, full_length: bool = False) -> BenchResult:
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
    valve_id : str, optional
        Identity of the valve under test, for the record.
    icd : Icd, optional
        Compiled ICD (the packaged one by default).
    observer : LoopObserver, optional
        Told the phases and shown the loop as it runs (live view, log lines).
    truth : FeedforwardParameters, optional
        True parameters, when the rig is simulated.
    check_gains : bool, optional
        Check the PID gains' margins with python-control first (default).
    classify : bool, optional
        Judge a trustworthy test with the classifier (default); off for
        baseline calibration.
    classifier_path : pathlib.Path, optional
        ONNX model to judge with; the packaged one by default.
    coil_temp_c : float, optional
        The coil's temperature at the start, to refer its measured resistance to 20 degC (20 degC if not given).
    stream_can_log : callable, optional
        Returns the file to stream the raw CAN log to while the test runs
        (called once the test is about to start), so that a killed process
        leaves a readable log.
    nominal_baseline : bool, optional
        Judge a variant that has no measured baseline against the nominal one (``--nominal-baseline``);
        by default such a test ends INVALID, "variant not calibrated".
    calibrate_command : str, optional
        The command that calibrates the variant on this rig, quoted in that reason.
    full_length : bool, optional
        Run the variant's whole duration; by default a classified test stops as soon as its verdict is certain
        or its model is known not to fit (:mod:`edc_bench.verdict.early_stop`).

    Returns
    -------
    BenchResult
        Also when the test was aborted: then the verdict is INVALID and the
        trace holds what was measured.

    Raises
    ------
    ConfigError
        If the variant's gains are unstable or marginal on its nominal plant.
    """
    margins = check_variant_gains(variant) if check_gains else None
    # loaded before the test: a damaged baseline file is refused now, not after it
    baseline = load_baseline(variant) if classify else None
    started = _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds")
    stop_rule = None
    if classify and not full_length and baseline is not None and (baseline.calibrated or nominal_baseline):
        from edc_bench.verdict.classifier import default_classifier
        from edc_bench.verdict.early_stop import EarlyStop

        stop_rule = EarlyStop(variant, baseline, default_classifier(str(classifier_path) if classifier_path else None))
    loop = BenchLoop(bus, clock, variant, icd or default_icd(), observer, stop_requested=stop_requested,
                     stop_rule=stop_rule)
    can_log_path = None
    stream = None
    if stream_can_log is not None:
        try:
            stream = StreamingCanLog(loop.frames, stream_can_log())
        except OSError as exc:  # a full disk, a folder that vanished: the frames stay in memory all the same
            loop.outcome.events.append(f"can.log could not be opened for streaming ({type(exc).__name__}: {exc}); "
                                       "every frame is kept in memory and written with the record")
    with interrupt_guard():
        if stream is not None:
            with stream:
                outcome = loop.run()
            can_log_path = stream.path if stream.complete else None
            if stream.error is not None:
                outcome.events.append(f"can.log could not be streamed during the test ({stream.error}); every frame "
                                      "is kept in memory and written with the record")
        else:
            outcome = loop.run()
    trace = loop.trace.view()
    timing = timing_summary(trace, variant.controller.period_s)
    timing["missed_replies"] = outcome.missed_replies
    timing["cpu_steal_s"] = outcome.cpu_steal_s
    timing["first_tick_unix_s"] = outcome.first_tick_unix_s
    if stop_rule is not None:  # the early stop's longest call, which a real-time tick had to wait for
        timing["stop_check_max_us"] = outcome.stop_check_max_s * 1e6
    if observer is not None:
        observer.phase(Phase.CLASSIFY)
    judgement = judge_run(variant, trace, loop.controller, outcome, timing, truth=truth, classify=classify,
                          classifier_path=classifier_path, coil_temp_c=coil_temp_c,
                          nominal_baseline=nominal_baseline, calibrate_command=calibrate_command,
                          baseline=baseline, real_rig=not isinstance(clock, SimulatedClock))
    return BenchResult(
        stop=stop_summary(variant, outcome, full_length, stop_rule is not None),
        judgement=judgement,
        timing=timing,
        outcome=outcome,
        margins=margins,
        variant=variant,
        valve_id=valve_id,
        started_at=started,
        clock="simulated" if isinstance(clock, SimulatedClock) else "real-time",
        trace=trace,
        frames=loop.frames,
        truth=truth,
        can_log_path=can_log_path,
    )


def stop_summary(variant: Variant, outcome: LoopOutcome, full_length: bool, early_stop: bool) -> dict:
    """Why and when the test ended, for the record."""
    max_s = variant.excitation.duration_s
    if outcome.stop is not None:
        out = dict(outcome.stop)
    elif outcome.abort is not None:
        out = {"reason": StopReason.ABORTED, "time_s": outcome.abort_time_s if outcome.abort_time_s is not None else
               outcome.ticks_run * variant.controller.period_s}
    else:
        out = {"reason": StopReason.FULL_LENGTH, "time_s": outcome.ticks_run * variant.controller.period_s}
    out.update(max_s=max_s, full_length=full_length, early_stop=early_stop)
    if out["reason"] is StopReason.FULL_LENGTH and not full_length:
        out["why_full_length"] = ("no early stop: the test is not classified against a calibrated baseline"
                                  if not early_stop else "the verdict was not certain before the maximum duration")
    return out


_channels = itertools.count()


def run_simulated_test(variant: Variant, valve: str | ValveSpec = "new", seed: int = 0, *,
                       valve_id: str = "", stiction: bool = True, sensor_noise: bool = True,
                       observer: LoopObserver | None = None, check_gains: bool = True,
                       classify: bool = True, stream_can_log: Callable[[], Path] | None = None,
                       adapter: AdapterModel | str | None = None, clock_wrapper: Callable[[Clock], Clock] | None = None,
                       coil_temp_c: float | None = None, nominal_baseline: bool = False,
                       calibrate_command: str | None = None, full_length: bool = False) -> BenchResult:
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
    coil_temp_c : float, optional
        What the technician states as the coil's temperature at the start (``--coil-temp-c``); not taken
        from the simulated valve, which the bench does not know.
    clock_wrapper : callable, optional
        Wraps the simulated clock (e.g. :class:`~edc_bench.testing.stalls.StallingClock` to inject host stalls).
    nominal_baseline, calibrate_command, full_length
        As :func:`run_bench_test`.

    Returns
    -------
    BenchResult
        With ``truth`` set to the simulated plant's parameters.
    """
    from edc_bench.physics.wear import is_faulty, resisting_force_n
    from edc_bench.sim.adapter import AdapterModel, parse_adapter
    from edc_bench.sim.inprocess import InProcessRig
    from edc_bench.sim.lockstep_bus import lockstep_pair
    from edc_bench.sim.rig import RigOptions, SimulatedRig

    spec = valve if isinstance(valve, ValveSpec) else parse_valve_spec(valve, variant)
    link = parse_adapter(adapter) if isinstance(adapter, str) else (adapter or AdapterModel())
    rig = SimulatedRig(variant, spec, seed, RigOptions(stiction=stiction, sensor_noise=sensor_noise))
    bench_bus, rig_bus = lockstep_pair(f"edc-bench-sim-{next(_channels)}")
    with bench_bus, rig_bus:
        clock: Clock = SimulatedClock(InProcessRig(rig_bus, rig, link, seed))
        if clock_wrapper is not None:
            clock = clock_wrapper(clock)
        result = run_bench_test(bench_bus, clock, variant, valve_id=valve_id or spec.label, observer=observer,
                                truth=rig.truth, check_gains=check_gains, classify=classify,
                                stream_can_log=stream_can_log, coil_temp_c=coil_temp_c,
                                nominal_baseline=nominal_baseline, calibrate_command=calibrate_command,
                                full_length=full_length)
    result.simulation = {
        "valve": {"label": spec.label, "clearance_mm": spec.clearance_mm, "roughness": spec.roughness,
                  "friction_scale": spec.friction_scale, "damping_scale": spec.damping_scale},
        "coil": {"resistance_20c_ohm": rig.plant_params.resistance_20c_ohm,
                 "temp_start_c": rig.plant_params.coil_temp_c, "temp_end_c": rig.plant.coil_temp_c,
                 "resistance_start_ohm": rig.plant_params.resistance_ohm,
                 "resistance_end_ohm": rig.plant.resistance_ohm},
        "seed": seed, "stiction": stiction, "sensor_noise": sensor_noise,
        "adapter": dataclasses.asdict(link),
        "faulty_by_physics": is_faulty(variant, spec),
        "resisting_force_n": resisting_force_n(variant, spec),
        "coulomb_friction_n": rig.plant_params.coulomb_friction_n,
        "damping_n_s_per_mm": rig.plant_params.damping_n_s_per_mm,
        "rig_counters": {"accepted": rig.firmware.counters.accepted, "bad_crc": rig.firmware.counters.bad_crc,
                         "bad_mode": rig.firmware.counters.bad_mode,
                         "watchdog_trips": rig.firmware.counters.watchdog_trips},
    }
    return result
