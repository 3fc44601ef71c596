"""How far the numbers behind a verdict can be trusted: identification error, interval coverage, early stops.

A shop's baseline is the mean of a few new valves measured on its own rig, so a population is judged here the same
way: ``calibration_valves`` simulated new valves are tested first (batch path, full length, trusted tests only, as
``edc-bench calibrate`` does), and their mean af and a1 are the baseline every used valve of the population is
judged against, each test stopped where the bench's early stop ends it. Against the simulation's truth:

- **identification error**: each judged valve's af and a1 (referred to the reference coil) over its plant's true
  values (:func:`~edc_bench.physics.feedforward.feedforward_truth`);
- **coverage**: whether the interval the early stop used (the variant's ``verdict_confidence``, relative to the
  baseline) holds the true ratio, the valve's true feature over the true mean of the calibration valves' features;
- **certain and wrong**: tests stopped as "verdict certain" whose verdict is not the one the classifier gives at the
  true ratios;
- **verdicts** against the physical labels, as ``edc-bench evaluate`` counts them, and the time to verdict.

Three populations: the default pump's, the hard variant's, and a stick-slip one: the default pump with Stribeck
friction (breakaway 1.5x Coulomb, within 2 mm/s) and a force constant varying by +/-6 % over the swing, whose valves
have up to 2.5x the Coulomb friction their wear gives while their damping is what their wear gives (a sticky valve,
as on the independently written rig of issue #37).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from edc_bench.config import load_variant, parse_variant
from edc_bench.config.models import PARAMETER_NAMES, Variant
from edc_bench.learning.evaluation import VerdictCounts, verdict_counts
from edc_bench.physics.valve import ValveSpec
from edc_bench.physics.wear import is_faulty
from edc_bench.population.batch import run_batch
from edc_bench.population.batch_stop import StopOutcome, BatchStopRule
from edc_bench.population.calibrate import population_run
from edc_bench.population.valves import draw_population
from edc_bench.verdict.baseline import Baseline, baseline_from_tests
from edc_bench.verdict.classifier import ValveClassifier, judge_of

AF, A1 = PARAMETER_NAMES.index("af"), PARAMETER_NAMES.index("a1")
FEATURES = ("af", "a1")
#: how close each feature is to be to its truth (issue #37's done-when): af within 2 %, a1 within 5 %
TOLERANCE_REL = {"af": 0.02, "a1": 0.05}
#: the stick-slip population's pump: Stribeck friction and a solenoid whose gain varies over the swing
STICK_SLIP_GAIN_VARIATION_REL = 0.06
STICK_SLIP_STICTION_RATIO = 1.5
STICK_SLIP_STRIBECK_MM_S = 2.0
#: a stick-slip valve's Coulomb friction over what its wear gives: uniform between these
STICK_SLIP_FRICTION_FACTOR = (1.0, 2.5)


def stick_slip_variant(base: Variant) -> Variant:
    """``base`` with Stribeck friction and a force constant varying by +/-6 % over the excitation's swing, named
    ``<name>-stick-slip``."""
    swing_mm = sum(tone.amplitude_mm for tone in base.excitation.active_tones)
    data = base.model_dump()
    data["coil"]["force_constant_variation_per_mm"] = STICK_SLIP_GAIN_VARIATION_REL / swing_mm
    data["valve"]["stiction_ratio"] = STICK_SLIP_STICTION_RATIO
    data["valve"]["stribeck_velocity_mm_s"] = STICK_SLIP_STRIBECK_MM_S
    data["pump"]["name"] = f"{base.pump.name}-stick-slip"
    return parse_variant(data)


def draw_sticky_valves(variant: Variant, count: int, seed: int) -> list[ValveSpec]:
    """The variant's used valves (:func:`~edc_bench.population.valves.draw_population`), each with its Coulomb
    friction multiplied by a factor drawn uniformly over :data:`STICK_SLIP_FRICTION_FACTOR`; damping untouched."""
    rng = np.random.default_rng([seed, 0x571C])
    low, high = STICK_SLIP_FRICTION_FACTOR
    return [replace(v, friction_scale=v.friction_scale * float(rng.uniform(low, high)))
            for v in draw_population(variant, count, seed)]


@dataclass(frozen=True)
class CoveragePopulation:
    """A population the coverage study judges: its pump and how its used valves are drawn."""

    name: str
    variant: Variant
    draw: Callable[[Variant, int, int], list[ValveSpec]]


def coverage_populations() -> dict[str, CoveragePopulation]:
    """The three populations by name: ``default``, ``hard``, ``stick-slip``."""
    default = load_variant("p-edc-default")
    return {"default": CoveragePopulation("default", default, draw_population),
            "hard": CoveragePopulation("hard", load_variant("p-edc-hard"), draw_population),
            "stick-slip": CoveragePopulation("stick-slip", stick_slip_variant(default), draw_sticky_valves)}


@dataclass(frozen=True)
class ShopBaseline:
    """A baseline measured on a few simulated new valves, and the truth it stands for."""

    measured: Baseline
    true_v: np.ndarray  # (2,) the true mean af and a1 of the calibration valves whose tests were trusted

    @property
    def error_rel(self) -> np.ndarray:
        """(2,) the measured af and a1 over their true values, minus 1."""
        return np.array([self.measured.af_v, self.measured.a1_v_s_per_mm]) / self.true_v - 1.0


def shop_baseline(variant: Variant, valves: int, seed: int) -> ShopBaseline:
    """The baseline ``edc-bench calibrate`` makes of ``valves`` simulated new valves (their trusted tests, full
    length), and the true mean of those valves' af and a1."""
    tests, result = population_run(variant, valves, seed)
    measured = baseline_from_tests(tests)  # a clear error when no test was trusted
    return ShopBaseline(measured, result.truth[result.trusted][:, [AF, A1]].mean(axis=0))


@dataclass(frozen=True)
class FeatureCoverage:
    """One feature (af or a1) over the tests judged at their stop, against the simulation's truth.

    Attributes
    ----------
    within : float
        The share within :data:`TOLERANCE_REL` of the truth.
    error_p50, error_p95 : float
        The median and 95th percentile of the |relative error|.
    bias : float
        The median signed relative error.
    covered : float
        The share whose interval holds the true ratio.
    half_width_p50 : float
        The interval's median half width, relative.
    baseline_error : float
        The baseline's relative error.
    """

    within: float
    error_p50: float
    error_p95: float
    bias: float
    covered: float
    half_width_p50: float
    baseline_error: float


@dataclass(frozen=True)
class CoverageFigures(VerdictCounts):
    """What the tests found at their stop, against the truth (:func:`coverage_figures`): the verdicts of the
    tests judged against the physical labels, and these."""

    #: the tests trusted at their stop
    judged: int
    #: the tests stopped certain; of those, the ones with a verdict other than the classifier's at the true ratios
    certain: int
    certain_wrong: int
    median_stop_s: float
    af: FeatureCoverage
    a1: FeatureCoverage


@dataclass(frozen=True)
class CoverageStudy(CoverageFigures):
    """A population judged against a baseline of a few new valves (:func:`coverage_study`)."""

    population: str
    variant: str
    #: the judging model's name
    model: str
    valves: int
    calibration_valves: int
    #: the baseline's trusted tests
    baseline_tests: int
    seed: int


def coverage_study(population: CoveragePopulation, classifier: ValveClassifier | None, count: int, seed: int,
                   calibration_valves: int = 5) -> CoverageStudy:
    """Judge ``count`` used valves of ``population`` against a baseline of ``calibration_valves`` new ones.

    The baseline's valves are drawn with ``seed + 1``, the population with ``seed``. They are judged by
    ``classifier``, or (None) by the model that judges the population's pump
    (:func:`~edc_bench.verdict.classifier.judge_of`).
    """
    variant = population.variant
    classifier = judge_of(variant, classifier)
    shop = shop_baseline(variant, calibration_valves, seed + 1)
    valves = population.draw(variant, count, seed)
    result = run_batch(variant, valves, [seed * 100_000 + n for n in range(count)],
                       stop=BatchStopRule.of(variant, classifier, shop.measured))
    assert result.stop is not None  # a run with a stop rule records its stops
    labels = np.array([is_faulty(variant, v) for v in valves])
    figures = coverage_figures(result.stop, result.parameters, result.truth, shop, classifier, labels)
    return CoverageStudy(**vars(figures), population=population.name, variant=variant.name, model=classifier.name,
                         valves=count, calibration_valves=calibration_valves, baseline_tests=shop.measured.tests,
                         seed=seed)


def coverage_figures(stopped: StopOutcome, parameters: np.ndarray, truth: np.ndarray, shop: ShopBaseline,
                     classifier: ValveClassifier, faulty: np.ndarray) -> CoverageFigures:
    """What the tests found at their stop, against the truth.

    Parameters
    ----------
    stopped : StopOutcome
        Each test's stop (its relative features, their interval's half widths, trusted, certain, when).
    parameters, truth : numpy.ndarray
        (N, 6) the identified parameters at the stop and the plants' true ones, both at the reference coil.
    shop : ShopBaseline
        The baseline the tests were judged against, with its truth.
    classifier : ValveClassifier
        What judged them.
    faulty : numpy.ndarray
        (N,) the physical labels.
    """
    judged = stopped.trusted
    n = len(judged)
    error = parameters[:, [AF, A1]] / truth[:, [AF, A1]] - 1.0
    true_rel = truth[:, [AF, A1]] / shop.true_v
    covered = np.abs(stopped.features_rel - true_rel) <= stopped.half_width_rel
    verdict_at_stop = np.full(n, "", dtype=object)
    if judged.any():
        verdict_at_stop[judged] = classifier.classify_many(stopped.features_rel[judged])[0]
    certain_wrong = stopped.certain & (verdict_at_stop != classifier.verdicts(true_rel))
    features = []
    for j, name in enumerate(FEATURES):
        e = error[judged, j]
        some = len(e) > 0
        features.append(FeatureCoverage(
            within=float((np.abs(e) <= TOLERANCE_REL[name]).mean()) if some else math.nan,
            error_p50=float(np.median(np.abs(e))) if some else math.nan,
            error_p95=float(np.percentile(np.abs(e), 95)) if some else math.nan,
            bias=float(np.median(e)) if some else math.nan,
            covered=float(covered[judged, j].mean()) if some else math.nan,
            half_width_p50=float(np.median(stopped.half_width_rel[judged, j])) if some else math.nan,
            baseline_error=float(shop.error_rel[j])))
    af, a1 = features
    return CoverageFigures(**vars(verdict_counts(verdict_at_stop[judged], faulty[judged])), judged=int(judged.sum()),
                           certain=int(stopped.certain.sum()), certain_wrong=int(certain_wrong.sum()),
                           median_stop_s=float(np.percentile(stopped.time_s, 50, method="higher")), af=af, a1=a1)


__all__ = [
    "TOLERANCE_REL",
    "CoverageFigures",
    "CoveragePopulation",
    "CoverageStudy",
    "FeatureCoverage",
    "ShopBaseline",
    "coverage_figures",
    "coverage_populations",
    "coverage_study",
    "draw_sticky_valves",
    "shop_baseline",
    "stick_slip_variant",
]
