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
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import can
import numpy as np

from edc_bench import __version__
from edc_bench.config.models import PARAMETER_NAMES, Variant
from edc_bench.control.fel import FelController
from edc_bench.control.stability import LoopMargins
from edc_bench.diagnosis.identification import Identification, analyse
from edc_bench.physics.feedforward import FeedforwardParameters
from edc_bench.physics.valve import ValveSpec, parse_valve_spec
from edc_bench.protocol import Icd, default_icd
from edc_bench.records.stream import StreamingCanLog
from edc_bench.runtime.clock import Clock, SimulatedClock
from edc_bench.runtime.gain_check import check_variant_gains
from edc_bench.runtime.loop import BenchLoop, LoopObserver, LoopOutcome
from edc_bench.runtime.signals import interrupt_guard, stop_requested
from edc_bench.runtime.timing import timing_summary
from edc_bench.runtime.trace import CanFrameLog

#: Verdict of a trustworthy test that was not classified (``classify=False``,
#: as in baseline calibration). Never reported as PASS.
UNCLASSIFIED = "UNCLASSIFIED"
INVALID = "INVALID"


@dataclass
class BenchResult:
    """Everything one bench test produced.

    Attributes
    ----------
    verdict : str
        ``PASS`` (reusable), ``MARGINAL`` (near the boundary: retest), ``FAIL``
        (replace), or ``INVALID`` (the test is not to be trusted; see
        ``reasons``; the classifier is never asked). ``UNCLASSIFIED`` when
        classification was switched off.
    reasons : list of str
        Why the verdict is what it is.
    parameters : dict
        ``name -> {"value", "std", "estimated"}`` for a3, a2, a1, a0, b, af.
    features : dict
        ``{"af": ..., "a1": ...}``, the diagnosis inputs.
    converged : bool
        af and a1 settled and stayed settled.
    truth : FeedforwardParameters or None
        The simulated plant's true parameters (simulated rig only).
    """

    verdict: str
    reasons: list[str]
    parameters: dict[str, dict[str, Any]]
    features: dict[str, float]
    converged: bool
    identification: Identification | None
    timing: dict[str, float]
    outcome: LoopOutcome
    margins: LoopMargins | None
    variant: Variant
    valve_id: str
    started_at: str
    clock: str
    trace: dict[str, np.ndarray]
    frames: CanFrameLog
    truth: FeedforwardParameters | None = None
    classification: dict[str, Any] | None = None
    baseline: dict[str, Any] | None = None
    simulation: dict[str, Any] | None = None
    software_version: str = __version__
    extra: dict[str, Any] = field(default_factory=dict)
    #: who and where: ``pump_serial``, ``station``, ``operator`` (set by the caller)
    identity: dict[str, str] = field(default_factory=dict)


def _judge(variant: Variant, outcome: LoopOutcome, ident: Identification | None,
           timing: dict[str, float]) -> list[str]:
    """Reasons the test is not trustworthy (empty if it is)."""
    reasons = []
    acc = variant.acceptance
    if outcome.abort_reason:
        reasons.append(f"aborted: {outcome.abort_reason}")
    if ident is None:
        return reasons or ["no identification"]
    if not outcome.abort_reason and not ident.converged:
        settle = ", ".join(f"{n} {ident.settle_s[n]:.1f} s" for n in ("af", "a1"))
        reasons.append(f"not converged: af and a1 must settle within {acc.settle_band_rel:.0%} for the last "
                       f"{acc.convergence_window_s:g} s (settle times {settle})")
    if not outcome.abort_reason and ident.condition_number > acc.max_condition_number:
        reasons.append(f"poorly conditioned regression: condition number {ident.condition_number:.3g} "
                       f"> {acc.max_condition_number:.3g} (excitation not rich enough)")
    ticks = max(int(timing.get("ticks", 0)), 1)
    if timing.get("overruns", 0) / ticks > acc.max_overrun_fraction:
        reasons.append(f"timing: {timing['overruns']} of {ticks} ticks overran "
                       f"(limit {acc.max_overrun_fraction:.1%})")
    if outcome.missed_replies / ticks > acc.max_missed_reply_fraction:
        reasons.append(f"bus: {outcome.missed_replies} of {ticks} replies missing "
                       f"(limit {acc.max_missed_reply_fraction:.1%})")
    return reasons


def run_bench_test(bus: can.BusABC, clock: Clock, variant: Variant, *, valve_id: str = "",
                   icd: Icd | None = None, observer: LoopObserver | None = None,
                   truth: FeedforwardParameters | None = None, check_gains: bool = True,
                   classify: bool = True, classifier_path: Path | None = None,
                   stream_can_log: Callable[[], Path] | None = None) -> BenchResult:
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
    stream_can_log : callable, optional
        Returns the file to stream the raw CAN log to while the test runs
        (called once the test is about to start), so that a killed process
        leaves a readable log.

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
    started = _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds")
    loop = BenchLoop(bus, clock, variant, icd or default_icd(), observer, stop_requested=stop_requested)
    with interrupt_guard():
        if stream_can_log is not None:
            with StreamingCanLog(loop.frames, stream_can_log()):
                outcome = loop.run()
        else:
            outcome = loop.run()
    trace = loop.trace.view()
    timing = timing_summary(trace, variant.controller.period_s)
    timing["missed_replies"] = outcome.missed_replies
    timing["cpu_steal_s"] = outcome.cpu_steal_s
    timing["first_tick_unix_s"] = outcome.first_tick_unix_s
    if observer is not None:
        observer.phase("classify")
    judged = judge_run(variant, trace, loop.controller, outcome, timing, truth=truth, classify=classify,
                       classifier_path=classifier_path)
    return BenchResult(
        **judged,
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
    )


def judge_run(variant: Variant, trace: dict[str, np.ndarray], controller: FelController | None,
              outcome: LoopOutcome, timing: dict[str, float], *, truth: FeedforwardParameters | None = None,
              classify: bool = True, classifier_path: Path | None = None) -> dict[str, Any]:
    """Identification, trust and verdict of a run, from its trace and its controller.

    Shared by the live test and :mod:`edc_bench.replay`, so a replay judges
    exactly as the test did.

    Returns
    -------
    dict
        ``verdict``, ``reasons``, ``classification``, ``baseline``,
        ``parameters``, ``features``, ``converged`` and ``identification``
        (the :class:`BenchResult` fields of the same names).
    """
    ident = analyse(trace, controller, variant) if controller is not None and len(trace["t_s"]) else None
    reasons = _judge(variant, outcome, ident, timing)
    parameters: dict[str, dict[str, Any]] = {}
    if ident is not None and controller is not None:
        estimated = {PARAMETER_NAMES[i] for i in controller.estimated}
        for name in PARAMETER_NAMES:
            entry: dict[str, Any] = {"value": ident.final[name], "std": ident.std[name],
                                     "estimated": name in estimated}
            if truth is not None:
                entry["truth"] = getattr(truth, name)
                entry["error_rel"] = ident.final[name] / getattr(truth, name) - 1.0
            parameters[name] = entry
    features = {n: (ident.final[n] if ident else math.nan) for n in ("af", "a1")}
    verdict = INVALID if reasons else UNCLASSIFIED
    classification = baseline_info = None
    if not reasons and classify:
        judged, baseline, classifier = classify_features(variant, features["af"], features["a1"], classifier_path)
        verdict = judged.verdict
        classification = classification_dict(judged, classifier)
        baseline_info = dataclasses.asdict(baseline)
        reasons = [f"{judged.model} model: P(faulty) = {judged.probability_faulty:.3f}, distance to the boundary "
                   f"{judged.distance:+.3f} (marginal band {classification['marginal_band']:g})"]
    return {
        "verdict": verdict,
        "reasons": reasons or ["test trustworthy; classification switched off"],
        "classification": classification,
        "baseline": baseline_info,
        "parameters": parameters,
        "features": features,
        "converged": bool(ident and ident.converged and not outcome.abort_reason),
        "identification": ident,
    }


def classify_features(variant: Variant, af: float, a1: float, classifier_path: Path | None = None):
    """Judge features with the classifier against the variant's baseline.

    Returns
    -------
    (Classification, Baseline, ValveClassifier)
        The judgement, the baseline and the classifier that judged.
    """
    from edc_bench.diagnosis.baseline import load_baseline
    from edc_bench.diagnosis.classifier import default_classifier

    baseline = load_baseline(variant)
    classifier = default_classifier(str(classifier_path) if classifier_path else None)
    return classifier.classify(*baseline.relative(af, a1)), baseline, classifier


def classification_dict(judged: Any, model: Any) -> dict[str, Any]:
    """A classification by ``model`` as plain data for records and JSON."""
    return {
        "verdict": judged.verdict, "probability_faulty": judged.probability_faulty, "distance": judged.distance,
        "features_rel": {"af": judged.features_rel[0], "a1": judged.features_rel[1]}, "model": judged.model,
        "threshold": model.threshold, "marginal_band": model.marginal_band,
        "training_data_sha256": model.metadata.get("edc_bench.training_data_sha256"),
    }


_channels = itertools.count()


def run_simulated_test(variant: Variant, valve: str | ValveSpec = "new", seed: int = 0, *,
                       valve_id: str = "", stiction: bool = True, sensor_noise: bool = True,
                       observer: LoopObserver | None = None, check_gains: bool = True,
                       classify: bool = True, stream_can_log: Callable[[], Path] | None = None) -> BenchResult:
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

    Returns
    -------
    BenchResult
        With ``truth`` set to the simulated plant's parameters.
    """
    from edc_bench.physics.wear import is_faulty, resisting_force_n
    from edc_bench.sim.inprocess import InProcessRig
    from edc_bench.sim.lockstep_bus import lockstep_pair
    from edc_bench.sim.rig import RigOptions, SimulatedRig

    spec = valve if isinstance(valve, ValveSpec) else parse_valve_spec(valve, variant)
    rig = SimulatedRig(variant, spec, seed, RigOptions(stiction=stiction, sensor_noise=sensor_noise))
    bench_bus, rig_bus = lockstep_pair(f"edc-bench-sim-{next(_channels)}")
    with bench_bus, rig_bus:
        clock = SimulatedClock(InProcessRig(rig_bus, rig))
        result = run_bench_test(bench_bus, clock, variant, valve_id=valve_id or spec.label, observer=observer,
                                truth=rig.truth, check_gains=check_gains, classify=classify,
                                stream_can_log=stream_can_log)
    result.simulation = {
        "valve": {"label": spec.label, "clearance_mm": spec.clearance_mm, "roughness": spec.roughness,
                  "friction_scale": spec.friction_scale, "damping_scale": spec.damping_scale},
        "seed": seed, "stiction": stiction, "sensor_noise": sensor_noise,
        "faulty_by_physics": is_faulty(variant, spec),
        "resisting_force_n": resisting_force_n(variant, spec),
        "coulomb_friction_n": rig.plant_params.coulomb_friction_n,
        "damping_n_s_per_mm": rig.plant_params.damping_n_s_per_mm,
        "rig_counters": {"accepted": rig.firmware.counters.accepted, "bad_crc": rig.firmware.counters.bad_crc,
                         "watchdog_trips": rig.firmware.counters.watchdog_trips},
    }
    return result
