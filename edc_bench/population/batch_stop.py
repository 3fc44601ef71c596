"""The bench's early stop in the batch path: each test ends where the loop's would.

After each whole period the loop asks :class:`~edc_bench.verdict.early_stop.EarlyStop` whether the verdict is
certain or the model does not fit; so does the batch, with the same function
(:func:`~edc_bench.verdict.early_stop.stop_flags`) over all valves still running. A valve that stops
leaves the batch, which then runs on with the others only: a population costs what its tests' real lengths
cost, not the full length each.

:class:`BatchStopRule` decides; :class:`StopOutcome` keeps what each valve's test had found when it stopped.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from edc_bench.config.models import PARAMETER_NAMES, Variant
from edc_bench.control.design import ControllerDesign
from edc_bench.identification.period_fit import FitSetup
from edc_bench.identification.trust import Problem
from edc_bench.verdict.baseline import Baseline, load_baseline
from edc_bench.verdict.classifier import ValveClassifier, default_classifier
from edc_bench.verdict.early_stop import Interval, relative_box, stop_flags

if TYPE_CHECKING:
    from edc_bench.population.batch import BatchIdentification

AF, A1 = PARAMETER_NAMES.index("af"), PARAMETER_NAMES.index("a1")


@dataclass(frozen=True)
class StopDecision:
    """The stop rule's answer after some periods, per valve still running."""

    stop: np.ndarray  # (N,) the test ends now
    features_rel: np.ndarray  # (N, 2) af and a1 over the baseline's (NaN: no fit yet)
    trusted: np.ndarray  # (N,) the judgement would trust the numbers
    misfit: np.ndarray  # (N,) the model does not fit: INVALID
    half_width_rel: np.ndarray  # (N, 2) the half widths of af's and a1's interval, relative (NaN: no fit yet)
    certain: np.ndarray  # (N,) trusted, and the verdict is the same over the whole interval box


@dataclass(frozen=True)
class BatchStopRule:
    """The loop's early stop for a batch: the classifier and the baseline a bench test of ``variant`` uses.

    Build it with :meth:`of` (or :meth:`shipped` for the model the variant's valves are judged by and the packaged
    baseline).
    """

    variant: Variant
    classifier: ValveClassifier
    baseline: Baseline
    interval: Interval

    @classmethod
    def of(cls, variant: Variant, classifier: ValveClassifier, baseline: Baseline) -> BatchStopRule:
        """The rule for ``variant``'s tests, judged by ``classifier`` against ``baseline``."""
        design = ControllerDesign.from_variant(variant)
        max_periods = FitSetup.from_variant(variant).blocks_in(design.ticks)
        return cls(variant, classifier, baseline, Interval.of(variant, max_periods))

    @classmethod
    def shipped(cls, variant: Variant) -> BatchStopRule:
        """The rule with the model ``variant``'s valves are judged by and ``variant``'s packaged baseline."""
        return cls.of(variant, default_classifier(variant=variant), load_baseline(variant, station=False))

    def decide(self, periods: int, last: bool, at: BatchIdentification, noise_v: float,
               reference_condition: float) -> StopDecision:
        """Which tests stop after ``periods`` whole periods (``last``: the test's full length, all of them).

        ``at`` is the identification then (:meth:`~edc_bench.population.batch.PeriodResults.at`); a test whose
        fit could not be solved yet runs on, or ends untrusted at its full length.
        """
        n = len(at.parameters)
        if at.fit is None:
            nothing, no_box = np.zeros(n, dtype=bool), np.full((n, 2), np.nan)
            return StopDecision(np.full(n, last), no_box, nothing, nothing, no_box, nothing)
        base = np.array([self.baseline.af_v, self.baseline.a1_v_s_per_mm])
        box = relative_box(at.parameters[:, [AF, A1]], at.fit, base, self.interval, self.baseline)
        centre, width = box.centre, box.half_width
        misfit, trusted, certain, _ = stop_flags(self.variant, self.classifier, at.fit, periods, centre, width,
                                                 noise_v, reference_condition)
        return StopDecision(certain | misfit | last, centre, trusted, misfit, width, certain)


class StopOutcome:
    """What each valve's test had found when it stopped (arrays over the batch's valves, in their order).

    Attributes
    ----------
    periods : numpy.ndarray
        (N,) whole periods each test ran.
    time_s : numpy.ndarray
        (N,) when each stopped (the end of its last period and the half smoothing window after it).
    features_rel, trusted, misfit, half_width_rel, certain : numpy.ndarray
        As :class:`StopDecision`'s, at the stop (``certain``: the test stopped because its verdict was certain).
    parameters : numpy.ndarray
        (N, 6) the identified parameters then, referred to the reference coil.
    converged, model_fits, problems : numpy.ndarray
        As :class:`~edc_bench.population.batch.BatchIdentification`'s, at the stop.
    condition_number, gain_variation_rel, systematic_rms_v : numpy.ndarray
        The period fit's figures at the stop (NaN where no fit was solved).
    coil_ohm, coil_end_ohm : numpy.ndarray
        The coil resistance the test measured, and the simulated coil's, at the stop.
    """

    def __init__(self, n: int) -> None:
        nan = np.full(n, np.nan)
        self.periods = np.zeros(n, dtype=np.int64)
        self.time_s = nan.copy()
        self.features_rel = np.full((n, 2), np.nan)
        self.trusted = np.zeros(n, dtype=bool)
        self.misfit = np.zeros(n, dtype=bool)
        self.half_width_rel = np.full((n, 2), np.nan)
        self.certain = np.zeros(n, dtype=bool)
        self.parameters = np.full((n, len(PARAMETER_NAMES)), np.nan)
        self.converged = np.zeros(n, dtype=bool)
        self.model_fits = np.zeros(n, dtype=bool)
        self.problems = np.zeros(n, dtype=np.int64)
        self.condition_number = nan.copy()
        self.gain_variation_rel = nan.copy()
        self.systematic_rms_v = nan.copy()
        self.coil_ohm = nan.copy()
        self.coil_end_ohm = nan.copy()

    def record(self, valves: np.ndarray, stop: np.ndarray, periods: int, time_s: float, decision: StopDecision,
               at: BatchIdentification, coil_ohm: np.ndarray, coil_end_ohm: np.ndarray) -> None:
        """The tests ``valves[stop]`` stop after ``periods`` periods (``stop`` a mask over the running ones)."""
        which = valves[stop]
        self.periods[which] = periods
        self.time_s[which] = time_s
        self.features_rel[which] = decision.features_rel[stop]
        self.trusted[which] = decision.trusted[stop]
        self.misfit[which] = decision.misfit[stop]
        self.half_width_rel[which] = decision.half_width_rel[stop]
        self.certain[which] = decision.certain[stop]
        self.parameters[which] = at.parameters[stop]
        self.converged[which] = at.converged[stop]
        self.model_fits[which] = at.model_fits[stop]
        self.problems[which] = at.problems[stop]
        if at.fit is not None:
            self.condition_number[which] = at.fit.condition_number[stop]
            self.gain_variation_rel[which] = at.fit.gain_variation_rel[stop]
            self.systematic_rms_v[which] = at.fit.systematic_rms_v[stop]
        self.coil_ohm[which] = coil_ohm[stop]
        self.coil_end_ohm[which] = coil_end_ohm[stop]

    def aborted(self, tripped: np.ndarray, tripped_s: np.ndarray) -> None:
        """The tests ``tripped`` (a mask) were aborted by the rig at ``tripped_s`` before they stopped: no verdict
        stands (the loop's test ends there, with what it had identified, untrusted)."""
        self.problems[tripped] |= int(Problem.ABORTED)
        for name in ("converged", "trusted", "certain"):
            getattr(self, name)[tripped] = False
        self.time_s[tripped] = tripped_s[tripped]


__all__ = ["BatchStopRule", "StopDecision", "StopOutcome"]
