"""From a finished run to its verdict: how far to trust it, then what the classifier says.

:func:`judge_run` is shared by the live test and replay, so a replay judges
exactly as the test did. Its :class:`Judgement` carries everything a record
and its report need to stand alone: the reference values the parameters are
compared with, the identity (file name and SHA-256) of the model that
judged, and the decision plane around the valve.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from edc_bench.config.models import PARAMETER_NAMES, Variant
from edc_bench.control.fel import FelController
from edc_bench.engine.outcome import LoopOutcome
from edc_bench.identification.analysis import Identification, ModelFit, analyse
from edc_bench.identification.coil_check import coil_finding, coil_reason
from edc_bench.identification.sections import CoilFinding
from edc_bench.identification.period_fit import DRIFT_MIN_PERIODS
from edc_bench.identification.trust import TRUST_PROBLEMS, Problem, trust_problems
from edc_bench.physics.coil import referred_from_estimate, volts_at_coil
from edc_bench.physics.feedforward import inductive_shares
from edc_bench.physics.feedforward import FeedforwardParameters, nominal_parameters
from edc_bench.section import FeaturePair, JudgedFeatures
from edc_bench.engine.tick_timing import TickTiming
from edc_bench.verdict.baseline import Baseline, load_baseline
from edc_bench.verdict.part import diagnose_parts, part_reasons
from edc_bench.verdict.part_sections import PartDiagnosis
from edc_bench.verdict.pc_stall import RIG_ON_THIS_PC_REASON, a_stall_can_cause, pc_stall_reason, pc_stall_s
from edc_bench.verdict.sections import (
    BaselineSummary,
    ClassificationSummary,
    DecisionPlane,
    ParameterEstimate,
    ReferenceValue,
)
from edc_bench.verdict.classifier import Classification, ValveClassifier, default_classifier
from edc_bench.verdict.verdicts import Verdict

#: The decision plane stored with a judged test: a square grid of P(faulty) over the relative features.
DECISION_PLANE_POINTS = 60
#: Its lower corner, and its upper corner at least (it grows to hold the valve).
DECISION_PLANE_MIN, DECISION_PLANE_MAX = 0.5, 2.6


@dataclass(frozen=True)
class Judgement:
    """The verdict of one run and everything behind it (frozen: :func:`judge_run` builds it once, when it knows all).

    Attributes
    ----------
    verdict : Verdict
        PASS, MARGINAL, FAIL, INVALID or UNCLASSIFIED.
    reasons : list of str
        Why the verdict is what it is.
    parameters : dict of str to ParameterEstimate
        a3, a2, a1, a0, b, af: value, standard error, estimated or fixed (with ``truth`` and ``error_rel`` on a
        simulated rig).
    features : FeaturePair
        af and a1, the diagnosis inputs (V and V s/mm), referred to the reference coil (the variant's nominal coil
        at 20 degC): they do not depend on this coil's resistance; NaN where not identified.
    features_volt : FeaturePair
        af and a1 in volts as identified with this test's coil (the paper's features), for comparison.
    converged : bool
        af and a1 settled and stayed settled, and the run was not aborted.
    identification : Identification or None
        Settle times, conditioning, uncertainty; None if nothing ran.
    reference_values : dict of str to ReferenceValue
        What each parameter is compared with: the variant's new-valve baseline for af and a1 when one was used,
        the data-sheet nominal value otherwise.
    classification : ClassificationSummary or None
        The classifier's judgement, with the model's identity.
    baseline : BaselineSummary or None
        The baseline the features were divided by.
    decision_plane : DecisionPlane or None
        P(faulty) on a grid around the valve (for the report), with the
        threshold and marginal band.
    coil : CoilFinding or None
        The coil's resistance measured in the test and its spec (:func:`~edc_bench.identification.coil_check.coil_finding`).
    problems : Problem
        What stands between the test and a verdict on the valve's wear, as values (the trust rule's problems,
        the variant not calibrated, the coil out of spec, the rack or the sensor at fault); ``reasons`` says them
        in words.
    part : PartDiagnosis or None
        Which part of the module is at fault, with every signature's figure (:mod:`edc_bench.verdict.part`); None
        where the test ran no period (nothing to measure) or replay judged a record from before it.
    """

    verdict: Verdict
    reasons: list[str]
    parameters: dict[str, ParameterEstimate]
    features: FeaturePair
    converged: bool
    identification: Identification | None
    reference_values: dict[str, ReferenceValue] = field(default_factory=dict)
    classification: ClassificationSummary | None = None
    baseline: BaselineSummary | None = None
    decision_plane: DecisionPlane | None = None
    features_volt: FeaturePair = FeaturePair()
    coil: CoilFinding | None = None
    problems: Problem = Problem.NONE
    part: PartDiagnosis | None = None


def verdict_of(problems: Problem, classified: Verdict | None) -> Verdict:
    """A test's verdict from its problems and the classifier's verdict on its valve (None: not classified).

    A test the trust rule does not trust is INVALID; else a coil out of spec fails the valve whatever its wear (it
    is replaced or repaired first; the coil's spec needs no baseline); else a pump whose rack binds or whose
    rack-travel sensor misreads is INVALID (the valve's figures are biased: the part diagnosis); else a variant
    without a measured baseline is INVALID; else the classifier's verdict stands, and a trustworthy test that was
    not classified (baseline calibration) is UNCLASSIFIED.

    The one place the rule is written: :func:`judge_run` decides with it, and
    :mod:`edc_bench.records.consistency` re-decides a record's verdict with it from the problems and the
    classification the record keeps.
    """
    if problems & TRUST_PROBLEMS:
        return Verdict.INVALID
    if Problem.COIL_OUT_OF_SPEC in problems:
        return Verdict.FAIL
    if Problem.PUMP_FAULT in problems:
        return Verdict.INVALID
    if Problem.NOT_CALIBRATED in problems:
        return Verdict.INVALID
    return Verdict.UNCLASSIFIED if classified is None else Verdict(classified)


def run_problems(variant: Variant, outcome: LoopOutcome, ident: Identification | None,
                 timing: TickTiming) -> Problem:
    """The trust rule (:func:`~edc_bench.identification.trust.trust_problems`) for one run."""
    if ident is None:
        aborted = Problem.ABORTED if outcome.aborted else Problem.NONE
        return aborted | Problem.NOT_IDENTIFIED
    fit = ident.model_fit
    flags = trust_problems(
        variant.acceptance, periods=ident.periods, settled=ident.settled, misfit=fit is not None and not fit.fits,
        condition_number=ident.condition_number, aborted=outcome.aborted, ticks=timing.ticks,
        ticks_late_or_lost=timing.ticks_late + outcome.ticks_lost, missed_replies=outcome.missed_replies)
    return Problem(int(flags))


def trust_reasons(variant: Variant, outcome: LoopOutcome, ident: Identification | None,
                  timing: TickTiming, problems: Problem | None = None) -> list[str]:
    """Why the run is not to be trusted, in words (empty if it is): the sentences of :func:`run_problems`."""
    problems = run_problems(variant, outcome, ident, timing) if problems is None else problems
    acc = variant.acceptance
    reasons = []
    if Problem.ABORTED in problems:
        reasons.append(f"aborted: {outcome.abort_reason}")
    if Problem.NOT_IDENTIFIED in problems:
        return reasons or ["no identification"]
    fit = ident.model_fit
    if Problem.MODEL_DOES_NOT_FIT in problems:
        reasons.append(model_fit_reason(fit))
    if Problem.TOO_FEW_PERIODS in problems:
        reasons.append(f"not converged: {ident.periods} whole excitation period(s) of {ident.period_s:g} s "
                       f"measured, at least {acc.min_periods} needed after the first (a longer test is needed)")
    if Problem.DRIFTING in problems and ident.periods_estimated < ident.periods:
        reasons.append(f"not converged: only {ident.periods_estimated} of {ident.periods} excitation periods kept "
                       "rows enough for an estimate of their own (the fit leaves out the rows host stalls or "
                       "missing replies touched, and those where the rack did not slide)")
    elif Problem.DRIFTING in problems:
        spread = "" if fit is None else (f" (period-to-period spread af {fit.spread_rel['af']:.1%}, "
                                         f"a1 {fit.spread_rel['a1']:.1%})")
        beyond = (f"more than {acc.settle_band_rel:.0%}" if ident.periods < DRIFT_MIN_PERIODS else
                  f"more than {acc.settle_band_rel:.0%} and more than their period-to-period noise explains")
        reasons.append(f"not converged: af and a1 were still drifting (their first {ident.periods // 2} and "
                       f"last {ident.periods - ident.periods // 2} excitation periods differ by {beyond})"
                       f"{spread}; retest")
    if Problem.POORLY_CONDITIONED in problems:
        reasons.append(f"poorly conditioned regression: condition number {ident.condition_number:.3g} "
                       f"> {acc.max_condition_number:.3g} (excitation not rich enough)")
    ticks = max(timing.ticks, 1)
    if Problem.TIMING in problems:
        late = timing.ticks_late + outcome.ticks_lost
        lost = f", {outcome.ticks_lost} lost in {outcome.gaps} host stalls" if outcome.ticks_lost else ""
        reasons.append(f"timing: {late} ticks overran or were lost ({timing.ticks_late} late{lost}), "
                       f"{late / ticks:.1%} of the {ticks} that ran (limit {acc.max_overrun_fraction:.1%}), "
                       + ("and the test was cut short" if Problem.ABORTED in problems else
                          "and what the fit kept without them did not give a trusted result")
                       + ": the PC stalled too often")
    if Problem.REPLIES_MISSING in problems:
        reasons.append(f"bus: {outcome.missed_replies} of {ticks} replies missing "
                       f"(limit {acc.max_missed_reply_fraction:.1%})")
    return reasons


#: What a technician does about a pump the model does not fit (the panel and the report show it).
MODEL_FIT_ADVICE = ("a longer test will not help. Check that the variant is this pump's (its coil and spring), "
                    "that the rack moves freely and the solenoid's armature and wiring are sound; a pump that "
                    "behaves like this needs its own variant (docs/faults.md, 'The model does not fit')")
MODEL_FIT_PREFIX = "the feedforward model does not fit this pump: "


def model_fit_reason(fit: ModelFit) -> str:
    """The INVALID reason for a model that does not fit: what was measured, and what to do."""
    return MODEL_FIT_PREFIX + "; ".join(fit.problems) + "; " + MODEL_FIT_ADVICE


def reference_values(variant: Variant, baseline: Baseline | None) -> dict[str, ReferenceValue]:
    """What each parameter is compared with: the baseline for af and a1 if one judged, else the nominal value."""
    out = {name: ReferenceValue(value=float(value), source="nominal")
           for name, value in nominal_parameters(variant)._asdict().items()}
    if baseline is not None:
        source = "baseline" if baseline.calibrated else "NOMINAL baseline (not calibrated)"
        out["af"] = ReferenceValue(value=baseline.af_v, source=source)
        out["a1"] = ReferenceValue(value=baseline.a1_v_s_per_mm, source=source)
    return out


def measured_resistance_ohm(trace: dict[str, np.ndarray], variant: Variant) -> float:
    """The coil resistance the loop used last (the reference coil's if none was measured)."""
    r = np.asarray(trace.get("coil_resistance_ohm", []), dtype=float)
    r = r[np.isfinite(r)]
    return float(r[-1]) if len(r) else variant.coil.resistance_ohm


def judge_run(variant: Variant, trace: dict[str, np.ndarray], controller: FelController | None,
              outcome: LoopOutcome, timing: TickTiming, *, truth: FeedforwardParameters | None = None,
              classify: bool = True, classifier_path: Path | None = None,
              coil_temp_c: float | None = None, nominal_baseline: bool = False,
              calibrate_command: str | None = None, baseline: Baseline | None = None,
              real_rig: bool = False, diagnose: bool = True) -> Judgement:
    """Identification, trust and verdict of a run, from its trace and its controller.

    Parameters
    ----------
    variant : Variant
        The variant as the run used it.
    trace : dict of numpy.ndarray
        The filled trace columns.
    controller : FelController or None
        The controller that ran (None if the run ended before the first tick).
    outcome : LoopOutcome
        What happened in the loop.
    timing : TickTiming
        Tick timing (``ticks``, ``ticks_late``).
    truth : FeedforwardParameters, optional
        The simulated plant's true parameters.
    classify : bool, optional
        Ask the classifier about a trustworthy run (default); off for baseline calibration.
    classifier_path : pathlib.Path, optional
        ONNX model to judge with; by default the one the variant's valves are judged by
        (:func:`~edc_bench.verdict.classifier.variant_model_path`).
    coil_temp_c : float, optional
        The coil's temperature at the start of the test, to refer its resistance to 20 degC; 20 degC if
        not given.
    nominal_baseline : bool, optional
        Judge a variant without a measured baseline against the nominal one from its physics (the
        engineer's explicit override); by default such a test is INVALID, "variant not calibrated".
    calibrate_command : str, optional
        The command that calibrates this variant on this rig, for that reason (a generic one by default).
    baseline : Baseline, optional
        Judge against this baseline (replay: the one the record was judged against); the variant's by default.
    real_rig : bool, optional
        The test ran on a bus, not the in-process simulated rig: a baseline measured only in simulation, or
        on fewer valves than recommended, is named in the reasons.
    diagnose : bool, optional
        Tell which part is at fault (default); off for replaying a record from before the part diagnosis, judged
        as the valve alone.
    """
    ident = analyse(trace, controller, variant) if controller is not None and len(trace["t_s"]) else None
    problems = run_problems(variant, outcome, ident, timing)
    reasons = trust_reasons(variant, outcome, ident, timing, problems)
    stall_s = pc_stall_s(outcome.abort, trace, variant)
    if stall_s > 0:  # the PC, not the rig or the bus, is what the technician checks
        problems |= Problem.PC_STALLED
        reasons.append(pc_stall_reason(stall_s, outcome.cpu_steal_s))
    elif timing.rig_on_this_pc and outcome.abort is not None and a_stall_can_cause(outcome.abort):
        problems |= Problem.PC_STALLED  # the rig's side of the PC stalled: no cable between them to check
        reasons.append(RIG_ON_THIS_PC_REASON)
    parameters: dict[str, ParameterEstimate] = {}
    inductive = inductive_shares(variant)._asdict()
    r_ref, r_hat = variant.coil.resistance_ohm, measured_resistance_ohm(trace, variant)
    final: dict[str, float] = {}
    if ident is not None and controller is not None:
        estimated = {PARAMETER_NAMES[i] for i in controller.estimated}
        for name in PARAMETER_NAMES:
            # estimated values as the reference coil gives them (the inductive shares put right)
            value = referred_from_estimate(inductive[name], ident.final[name], r_ref, r_hat) \
                if name in estimated else ident.final[name]
            final[name] = value
            true_value = None if truth is None else getattr(truth, name)
            parameters[name] = ParameterEstimate(
                value=value, std=ident.std[name], estimated=name in estimated, truth=true_value,
                error_rel=None if true_value is None else value / true_value - 1.0)
    af, a1 = final.get("af", math.nan), final.get("a1", math.nan)
    features = FeaturePair(af=af, a1=a1)
    coil = coil_finding(variant, trace, coil_temp_c)
    bad_coil = coil_reason(coil) if coil is not None else None
    problems |= Problem.COIL_OUT_OF_SPEC if bad_coil else Problem.NONE
    converged = bool(ident and ident.converged and not outcome.aborted)
    part = _part_at_fault(variant, trace, parameters, baseline, features, outcome, problems) \
        if diagnose and ident is not None else None
    if part is not None and not part.valve_judged:  # the rack or the sensor biases the valve's figures: not judged
        problems |= Problem.PUMP_FAULT
        reasons = part_reasons(part) + reasons
    features_volt = FeaturePair(af=volts_at_coil(inductive["af"], af, r_ref, r_hat),
                                a1=volts_at_coil(inductive["a1"], a1, r_ref, r_hat))
    # built once, at the end of the branch that decides it: a Judgement is frozen
    if reasons or not classify:
        if reasons:  # not trusted: why, and the coil
            said = reasons + ([bad_coil] if bad_coil else [])
        else:  # a coil out of spec fails the valve (verdict_of): it is replaced or repaired first
            said = [bad_coil] if bad_coil else ["test trustworthy; classification switched off"]
        return Judgement(
            verdict=verdict_of(problems, None), reasons=said,
            parameters=parameters, features=features, converged=converged, identification=ident,
            reference_values=reference_values(variant, None), features_volt=features_volt, coil=coil,
            problems=problems, part=part)
    baseline = baseline if baseline is not None else load_baseline(variant)
    if not baseline.calibrated and not nominal_baseline:
        problems |= Problem.NOT_CALIBRATED
        return Judgement(
            verdict=verdict_of(problems, None),
            reasons=([bad_coil] if bad_coil else []) + [not_calibrated_reason(variant, calibrate_command)],
            parameters=parameters, features=features, converged=converged, identification=ident,
            reference_values=reference_values(variant, None), features_volt=features_volt, coil=coil,
            problems=problems, part=part)  # no baseline: nothing was compared with it
    judged, classifier = classify_against(baseline, af, a1, classifier_path, variant)
    classified = (f"{judged.model} model: P(faulty) = {judged.probability_faulty:.3f}, distance to the boundary "
                  f"{judged.distance:+.3f} (marginal band {classifier.marginal_band:g})")
    said = [bad_coil, f"the valve itself: {judged.verdict}; {classified}"] if bad_coil else [classified]
    if not baseline.calibrated:
        said.insert(0, nominal_baseline_warning(variant, calibrate_command))
    else:
        said += baseline_cautions(baseline, variant, calibrate_command, real_rig)
    return Judgement(
        verdict=verdict_of(problems, Verdict(judged.verdict)), reasons=said, parameters=parameters,
        features=features, converged=converged, identification=ident,
        reference_values=reference_values(variant, baseline), classification=classification_summary(judged, classifier),
        baseline=baseline.summary(), decision_plane=decision_plane(classifier, judged.features_rel),
        features_volt=features_volt, coil=coil, problems=problems, part=part)


#: The bench's own faults: with them, what the fit gives (the friction along the stroke, a2, a0, b) says nothing of
#: the pump
BENCH_TROUBLE = (Problem.NOT_IDENTIFIED | Problem.TOO_FEW_PERIODS | Problem.TIMING | Problem.REPLIES_MISSING
                 | Problem.PC_STALLED)


def _part_at_fault(variant: Variant, trace: dict[str, np.ndarray], parameters: dict[str, ParameterEstimate],
                   baseline: Baseline | None, features: FeaturePair, outcome: LoopOutcome,
                   problems: Problem) -> PartDiagnosis:
    """Which part is at fault (:func:`~edc_bench.verdict.part.diagnose_parts`), against ``baseline`` (the variant's
    by default): the fitted figures only from periods the bench ran as it should."""
    from edc_bench.identification.signatures import measure

    against = baseline if baseline is not None else load_baseline(variant)
    af, a1 = features.numbers()
    relative = (af / against.af_v, a1 / against.a1_v_s_per_mm) if against.af_v > 0 else None
    return diagnose_parts(variant, measure(variant, trace), parameters, against, relative,
                          fit_trusted=not outcome.aborted and not problems & BENCH_TROUBLE)


def baseline_cautions(baseline: Baseline, variant: Variant, calibrate_command: str | None,
                      real_rig: bool) -> list[str]:
    """What a technician should know about a measured baseline: too few valves, or never measured on a rig."""
    from edc_bench.verdict.baseline import RECOMMENDED_TESTS

    command = calibrate_command or default_calibrate_command(variant)
    out = []
    if baseline.tests < RECOMMENDED_TESTS:
        out.append(f"caution: the baseline rests on {baseline.tests} new-valve test(s) (at least "
                   f"{RECOMMENDED_TESTS} recommended; new valves differ by several per cent): '{command}'")
    if real_rig and not baseline.measured_on_rig:
        out.append(f"caution: the baseline was measured in simulation ({baseline.source}), not on a rig: "
                   f"calibrate this rig with '{command}'")
    return out


def default_calibrate_command(variant: Variant, rig_arguments: Sequence[str] = ()) -> str:
    """The calibrate command for a variant, with the rig's flags (``--valve new`` for the simulated rig)."""
    import shlex

    from edc_bench.config.loader import variant_argument

    return shlex.join(["edc-bench", "calibrate", "--variant", variant_argument(variant), *rig_arguments, "--append"])


def not_calibrated_reason(variant: Variant, calibrate_command: str | None = None) -> str:
    """Why a test on a variant without a measured baseline is INVALID, and the command that fixes it."""
    command = calibrate_command or default_calibrate_command(variant)
    return (f"variant not calibrated: {variant.name} has no measured new-valve baseline, and af and a1 judged "
            f"against figures computed from its data sheet can turn a reusable valve into FAIL. Mount a known-new "
            f"valve and run '{command}' once per valve (at least 5 valves); or judge against the nominal baseline "
            f"anyway with --nominal-baseline")


def nominal_baseline_warning(variant: Variant, calibrate_command: str | None = None) -> str:
    """What a verdict judged against the nominal baseline says first."""
    command = calibrate_command or default_calibrate_command(variant)
    return (f"judged against the NOMINAL baseline (--nominal-baseline): {variant.name} is not calibrated, so af "
            f"and a1 were compared with figures computed from its data sheet, not measured on new valves; this "
            f"verdict may be wrong. Calibrate with '{command}'")


def classify_features(variant: Variant, af: float, a1: float,
                      classifier_path: Path | None = None) -> tuple[Classification, Baseline, ValveClassifier]:
    """Judge features with the classifier against the variant's baseline.

    Returns
    -------
    (Classification, Baseline, ValveClassifier)
        The judgement, the baseline and the classifier that judged.
    """
    baseline = load_baseline(variant)
    judged, classifier = classify_against(baseline, af, a1, classifier_path, variant)
    return judged, baseline, classifier


def classify_against(baseline: Baseline, af: float, a1: float, classifier_path: Path | None = None,
                     variant: Variant | None = None) -> tuple[Classification, ValveClassifier]:
    """Judge features with the classifier against ``baseline``; the judgement and the classifier that judged.

    The classifier is ``classifier_path``'s, else the one ``variant``'s valves are judged by
    (:func:`~edc_bench.verdict.classifier.variant_model_path`), else the station's."""
    classifier = default_classifier(str(classifier_path) if classifier_path else None, variant)
    return classifier.classify(*baseline.relative(af, a1)), classifier


def classification_summary(judged: Classification, model: ValveClassifier) -> ClassificationSummary:
    """A classification by ``model`` as records and JSON keep it, naming the model exactly."""
    return ClassificationSummary(
        verdict=judged.verdict, probability_faulty=judged.probability_faulty, distance=judged.distance,
        features_rel=JudgedFeatures(af=judged.features_rel[0], a1=judged.features_rel[1]), model=judged.model,
        model_name=model.name, model_file=model.path.name, model_sha256=model.sha256,
        threshold=model.threshold, marginal_band=model.marginal_band,
        training_data_sha256=model.metadata.get("edc_bench.training_data_sha256"))


def decision_plane(classifier: ValveClassifier, features_rel: tuple[float, float],
                   points: int = DECISION_PLANE_POINTS) -> DecisionPlane:
    """P(faulty) on a square grid of relative features that holds the baseline and the valve.

    The report draws the boundary (P at the threshold) and the marginal band
    from it, without the model.
    """
    hi = max(DECISION_PLANE_MAX, float(np.nanmax(np.asarray(features_rel) * 1.25)))
    _, _, p = classifier.boundary_grid((DECISION_PLANE_MIN, hi), (DECISION_PLANE_MIN, hi), n=points)
    return DecisionPlane(af_rel_range=(DECISION_PLANE_MIN, hi), a1_rel_range=(DECISION_PLANE_MIN, hi),
                         p_faulty=np.round(p, 5).tolist(), threshold=classifier.threshold,
                         marginal_band=classifier.marginal_band)
