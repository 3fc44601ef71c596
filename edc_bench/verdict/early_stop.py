"""Stop a test as soon as its verdict is known: after each whole excitation period, is it?

A test may stop once, after at least ``acceptance.min_periods`` whole periods
(:mod:`edc_bench.identification.period_fit`):

- **the verdict is certain**: the fit has settled, its regression is well
  conditioned, the model fits, and the verdict at af and a1 is the same at
  every corner of their ``verdict_confidence`` interval (relative to the
  baseline, standard errors of the mean over the periods); or
- **the model does not fit**: a longer test will not help.

Otherwise the test runs on, up to the variant's duration. Before each period
ends, :attr:`EarlyStop.expected_end_s` says when the test is expected to end:
the first period at which the interval, shrinking as 1/sqrt(periods) (and as
Student's t quantile falls with the periods' degrees of freedom), would
leave the verdict unchanged.

The loop calls :meth:`EarlyStop.check` at the ticks in
:attr:`EarlyStop.check_ticks` (bench layer: :func:`edc_bench.bench.run_bench_test`),
in order: inside the tick in simulated time, in a worker thread beside the
ticks in real time (:mod:`edc_bench.runtime.stop_worker`).
The work is spread so that no call costs more than a few ticks' time, however
long the test and its variant (the record's ``timing.stop_check_max_us``
gives each test's longest call; docs/bench-test.md the measured range):

- every :data:`STEP_TICKS` ticks the rows completed since the last step are
  fed (their replies in: the feed lags by the oldest reply the loop accepts);
- at a period's end the fit is solved with the period's last rows as they
  stand (fed for good by the next steps, their replies in) and the stop rule
  asked (one classifier call, five points);
- the expected end is searched a candidate period per step (more if the
  test has more periods left than a period has steps), half a step after
  each feed, until found (the live view shows the earliest it can be
  meanwhile).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from statistics import NormalDist

import numpy as np

from edc_bench.config.models import PARAMETER_NAMES, Variant
from edc_bench.control.design import ControllerDesign
from edc_bench.engine.outcome import PeriodDecision, StopDecision, StopReason
from edc_bench.engine.replies import max_reply_age_ticks
from edc_bench.identification.analysis import judges_model_fit, model_fit_problems, model_fits
from edc_bench.identification.period_fit import (
    MISFIT_ALLOWANCE,
    RESIDUAL_ALLOWANCE,
    BlockAccumulator,
    FitSetup,
    PeriodFit,
    accumulate,
    expected_drive_noise_v,
    reference_condition_number,
    solve,
    trace_rows,
)
from edc_bench.identification.student_t import t_quantile
from edc_bench.identification.trust import judged_condition_number, trust_problems
from edc_bench.physics.coil import referred_from_estimate
from edc_bench.physics.feedforward import inductive_shares
from edc_bench.section import FeaturePair
from edc_bench.verdict.baseline import Baseline
from edc_bench.verdict.classifier import ValveClassifier

#: Ticks between two feeds of rows (and between two steps of the expected-end search): each a fraction of a tick.
STEP_TICKS = 100


class EarlyStop:
    """Decides after each excitation period whether the test may end.

    Parameters
    ----------
    variant : Variant
        The variant as the test runs it.
    baseline : Baseline
        What af and a1 are judged against.
    classifier : ValveClassifier
        What judges them.
    """

    def __init__(self, variant: Variant, baseline: Baseline, classifier: ValveClassifier) -> None:
        self.variant, self.baseline, self.classifier = variant, baseline, classifier
        self.setup = setup = FitSetup.from_variant(variant)
        ticks = int(round(variant.excitation.duration_s / setup.period_s))
        self.max_periods = setup.blocks_in(ticks)
        self.acc = BlockAccumulator(setup, max(self.max_periods, 1))
        #: tick -> whole periods the trace holds once that tick has its sample: where the stop rule is asked
        self.period_ends = {setup.end_tick(b): b for b in range(1, self.max_periods + 1)}
        #: a row is fed once every sample its smoothing reaches is in, replies as old as the loop accepts included
        self.feed_lag_ticks = setup.window // 2 + max_reply_age_ticks(variant) + 1
        # counted back from each period's end, so that the end has only the last few rows left to feed
        self.feed_ticks = {end - 1 - j * STEP_TICKS for end in self.period_ends
                           for j in range(-(-setup.block_ticks // STEP_TICKS))}
        self.search_ticks = {k - STEP_TICKS // 2 for k in self.feed_ticks} - set(self.period_ends) - self.feed_ticks
        #: every tick after which :meth:`check` wants to be called
        self.check_ticks = set(self.period_ends) | self.feed_ticks | self.search_ticks
        # a period's end decides (a fit, its interval, the classifier): in real time beside the ticks
        self.decision_ticks = set(self.period_ends)
        #: candidate periods each search step tries: enough to finish between two period ends (the fewest steps)
        ends = sorted(self.period_ends)
        steps = min((sum(1 for t in self.search_ticks if a < t < b) for a, b in zip(ends, ends[1:])), default=1)
        self.search_per_step = max(1, -(-self.max_periods // max(steps, 1)))
        self.duration_s = ticks * setup.period_s
        self.expected_end_s = setup.end_s(min(variant.acceptance.min_periods, self.max_periods))
        #: True while :attr:`expected_end_s` is only the earliest the test can end (before the first decision, a
        #: fit not trusted yet, a search not finished): the live view says "at least"
        self.expected_end_is_earliest = True
        #: the last period-end decision, for the live view; None before the first
        self.latest: PeriodDecision | None = None
        self.fed_to_tick = setup.first_tick  # rows of ticks before this one are in the accumulator
        # centre, the half width's shrinking part and its fixed part, periods, the next candidate
        self._search: tuple[np.ndarray, np.ndarray, np.ndarray, int, int] | None = None
        self._r_ref = variant.coil.resistance_ohm
        self._inductive = inductive_shares(variant)
        self._noise_v = expected_drive_noise_v(variant)
        self._reference_condition = reference_condition_number(ControllerDesign.from_variant(variant))
        self.interval = Interval.of(variant, self.max_periods)
        self._base = np.array([baseline.af_v, baseline.a1_v_s_per_mm])
        # the classifier's first call costs several times a later one: paid now, before the loop's first tick
        certain_verdicts(classifier, np.ones((1, 2)), np.full((1, 2), 0.01))

    def _feed(self, to_tick: int, columns: dict[str, np.ndarray]) -> None:
        """Add the rows of ticks ``fed_to_tick .. to_tick - 1`` from the trace's columns."""
        if to_tick > self.fed_to_tick:
            self._add_rows(self.acc, to_tick, columns)
            self.fed_to_tick = to_tick

    def _add_rows(self, acc: BlockAccumulator, to_tick: int, columns: dict[str, np.ndarray]) -> None:
        """Add the rows of ticks ``fed_to_tick .. to_tick - 1`` to ``acc``."""
        start, half = self.fed_to_tick, self.setup.window // 2
        # the smoothing of a row reaches half a window either side, and the next sample: rows() leaves the span's
        # edges out, so the span reaches that far beyond the rows fed
        lo = start - half
        span = slice(lo, to_tick + half + 1)
        accumulate(self.setup, acc, lo, *trace_rows(self.setup, columns, self._r_ref, span))

    def _solve_with_pending(self, periods: int, columns: dict[str, np.ndarray]) -> PeriodFit | None:
        """The fit over ``periods`` blocks with the last block's rows not yet fed for good added as they stand now
        (a reply still on its way counts as missing, as in a test stopped here), to a copy of the sums: the later
        steps feed those rows for good, with their replies."""
        trial = self.acc.copy()
        end = self.setup.first_tick + periods * self.setup.block_ticks
        if end > self.fed_to_tick:
            self._add_rows(trial, end, columns)
        return solve(trial, periods, self.variant.acceptance.settle_band_rel)

    def _search_step(self) -> None:
        """One candidate period of the expected-end search: would the interval, shrunk to it, leave the verdict
        alone? (one classifier call, five points)"""
        if self._search is None:
            return
        centre, statistical, fixed, periods, more = self._search
        if more > self.max_periods:
            self.expected_end_s, self._search = self.duration_s, None
            self.expected_end_is_earliest = False
            return
        # enough candidates per step to finish before the next period's end (one, unless the test is long)
        candidates = np.arange(more, min(more + self.search_per_step, self.max_periods + 1))
        boxes = certain_verdicts(self.classifier, np.repeat(centre, len(candidates), axis=0),
                                 statistical * self.interval.shrink(periods, candidates)[:, None] + fixed)
        if boxes.any():
            self.expected_end_s, self._search = self.setup.end_s(int(candidates[np.argmax(boxes)])), None
            self.expected_end_is_earliest = False
        else:  # not before the next candidate, at the earliest
            after = int(candidates[-1]) + 1
            self.expected_end_s = self.setup.end_s(min(after, self.max_periods))
            self._search = (centre, statistical, fixed, periods, after)

    def check(self, k: int, columns: dict[str, np.ndarray]) -> StopDecision | None:
        """At tick ``k`` (one of :attr:`check_ticks`): the reason to stop now, with its figures, or None."""
        periods = self.period_ends.get(k)
        if periods is None:
            if k in self.feed_ticks:
                self._feed(k - self.feed_lag_ticks, columns)
            else:
                self._search_step()
            return None
        self._search = None  # the new period's figures replace an unfinished search
        self.expected_end_is_earliest = True
        acc, setup = self.variant.acceptance, self.setup
        # rows whose samples are final for good; the period's last few wait for replies still on their way
        self._feed(k - self.feed_lag_ticks, columns)
        if periods < acc.min_periods:
            self.expected_end_s = setup.end_s(min(acc.min_periods, self.max_periods))
            return None
        fit = self._solve_with_pending(periods, columns)
        if fit is None:
            self.expected_end_s = setup.end_s(min(periods + 1, self.max_periods))
            return None
        parameters = np.array([[referred_from_estimate(self._inductive[PARAMETER_NAMES.index(name)],
                                                       float(fit.value(name)[0]), self._r_ref,
                                                       float(columns["coil_resistance_ohm"][k]))
                                for name in ("af", "a1")]])
        box = relative_box(parameters, fit, self._base, self.interval, self.baseline)
        centre, half_width = box.centre, box.half_width
        misfit, trusted, certain, verdicts = stop_flags(self.variant, self.classifier, fit, periods, centre,
                                                        half_width, self._noise_v, self._reference_condition)
        self.latest = PeriodDecision(periods=periods, af_rel=float(centre[0, 0]), a1_rel=float(centre[0, 1]),
                                     af_half_width_rel=float(half_width[0, 0]),
                                     a1_half_width_rel=float(half_width[0, 1]), verdict=str(verdicts[0]))
        time_s = setup.end_s(periods)
        if misfit[0]:
            return StopDecision(StopReason.MODEL_DOES_NOT_FIT, time_s, periods,
                                problems=tuple(model_fit_problems(self.variant, fit, self._noise_v)))
        if certain[0]:
            def pair(figures: np.ndarray) -> FeaturePair:
                return FeaturePair(af=float(figures[0, 0]), a1=float(figures[0, 1]))

            return StopDecision(StopReason.VERDICT_CERTAIN, time_s, periods, verdict=str(verdicts[0]),
                                confidence=acc.verdict_confidence, features_rel=pair(centre),
                                half_width_rel=pair(half_width), misfit_half_width_rel=pair(box.misfit),
                                baseline_half_width_rel=pair(box.baseline), residual_half_width_rel=pair(box.residual))
        if not trusted[0]:  # not settled or conditioned yet: at the next period at the earliest
            self.expected_end_s = setup.end_s(min(periods + 1, self.max_periods))
            return None
        # when would the interval, shrinking with more periods (Interval.shrink), leave the verdict alone? Searched
        # a period at a time over the next steps (all at once would cost a classifier call per remaining period in
        # this tick)
        self._search = (centre, box.statistical, box.fixed, periods, periods + 1)
        self.expected_end_s = setup.end_s(min(periods + 1, self.max_periods))  # the earliest it can be, meanwhile
        return None


@dataclass(frozen=True)
class Interval:
    """How many standard errors either side of an estimate make the variant's ``verdict_confidence`` interval.

    The standard error from the periods' spread rests on few periods (two degrees of freedom from three), so it
    takes Student's t quantile for them; the least-squares one, on thousands of rows, the normal quantile.

    Attributes
    ----------
    z : float
        Normal quantile.
    t : numpy.ndarray
        Student's t quantile by degrees of freedom (index 0: NaN).
    """

    z: float
    t: np.ndarray

    @classmethod
    def of(cls, variant: Variant, max_periods: int) -> Interval:
        """The quantiles for ``variant``'s confidence, up to ``max_periods`` periods."""
        q = 0.5 + variant.acceptance.verdict_confidence / 2.0
        t = [math.nan] + [t_quantile(q, dof) for dof in range(1, max(max_periods, 2))]
        return cls(NormalDist().inv_cdf(q), np.array(t))

    def shrink(self, periods: int, more: np.ndarray) -> np.ndarray:
        """How a half width after ``periods`` periods would shrink after ``more`` (1/sqrt(periods), and the spread's
        quantile with its degrees of freedom)."""
        more = np.asarray(more)
        t_now = self.t[min(periods - 1, len(self.t) - 1)]
        t_then = self.t[np.minimum(more - 1, len(self.t) - 1)]
        return np.sqrt(periods / more) * t_then / t_now


@dataclass(frozen=True)
class RelativeBox:
    """af and a1 relative to the baseline, and the half width of their interval, in its four parts: (N, 2) each.

    Attributes
    ----------
    centre : numpy.ndarray
        The ratios to the baseline.
    statistical : numpy.ndarray
        The test's own noise: the larger of t standard errors from the periods' spread and z least-squares ones
        (NaN, no box, with fewer than two periods). It shrinks with more periods (:meth:`Interval.shrink`).
    misfit : numpy.ndarray
        :data:`MISFIT_ALLOWANCE` times the difference between the test's core shift and the baseline's mean one,
        times the ratio: what the model misses at reversals moves the ratio by the difference between the
        valve's share and the baseline's. More periods do not shrink it.
    baseline : numpy.ndarray
        The noise of the baseline's tests (:meth:`~edc_bench.verdict.baseline.Baseline.noise_rel`) times the
        ratio: it moves every ratio judged against the baseline.
    residual : numpy.ndarray
        The model's misfit elsewhere: :data:`RESIDUAL_ALLOWANCE` times the residual's repeating part beyond the
        baseline's tests' (in quadrature), over the feature's term in the drive, times the ratio. More periods do
        not shrink it.
    """

    centre: np.ndarray
    statistical: np.ndarray
    misfit: np.ndarray
    baseline: np.ndarray
    residual: np.ndarray

    @property
    def fixed(self) -> np.ndarray:
        """The parts more periods do not shrink."""
        return self.misfit + self.baseline + self.residual

    @property
    def half_width(self) -> np.ndarray:
        """The whole half width: the parts added (they are not independent noises to add in quadrature: the
        misfit is the same in every period)."""
        return self.statistical + self.fixed


def relative_box(parameters: np.ndarray, fit: PeriodFit, base: np.ndarray, interval: Interval,
                 baseline: Baseline | None = None) -> RelativeBox:
    """af and a1 relative to the baseline and their interval (:class:`RelativeBox`), for N tests.

    ``parameters``: (N, 2) af and a1 referred to the reference coil; ``base``: the baseline's af and a1;
    ``baseline``: the baseline, for its own uncertainty (its tests' noise, core shifts and repeating residual; none
    if not given: the whole repeating residual is then taken for misfit).
    """
    t = interval.t[np.clip(fit.periods_used - 1, 0, len(interval.t) - 1)][:, None]
    columns = [fit.columns.index("af"), fit.columns.index("a1")]
    half = np.maximum(t * fit.spread_se[:, columns], interval.z * fit.ls_std[:, columns])
    centre = parameters / base
    with np.errstate(divide="ignore", invalid="ignore"):
        shift_rel = fit.core_shift[:, columns] / fit.theta[:, columns]
    base_shift, base_noise = ((np.zeros(2), np.zeros(2)) if baseline is None
                              else (baseline.core_shift_rel(), baseline.noise_rel(interval.z)))
    return RelativeBox(centre, half / np.abs(base), MISFIT_ALLOWANCE * np.abs(shift_rel - base_shift) * np.abs(centre),
                       base_noise * np.abs(centre), _residual_rel(fit, columns, baseline) * np.abs(centre))


def _residual_rel(fit: PeriodFit, columns: list[int], baseline: Baseline | None) -> np.ndarray:
    """:data:`RESIDUAL_ALLOWANCE` times the residual's repeating part beyond the baseline's tests' mean one (in
    quadrature), over each of ``columns``' term in the drive: (N, len(columns)), relative to the coefficient.

    The baseline's new valves leave their own repeating residual (the smoothing's, the friction's at reversals)
    and their share of it is in the baseline; what a valve leaves beyond that, were it all in a term, would move
    the term's coefficient by that much over the term. 0 where the repeating part is not known (one period)."""
    reference_v = 0.0 if baseline is None else baseline.systematic_rms_v()
    systematic = np.nan_to_num(fit.systematic_rms_v, nan=0.0)
    beyond_v = np.sqrt(np.maximum(systematic ** 2 - reference_v ** 2, 0.0))
    term = fit.term_rms_v[:, columns]
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(term > 0, RESIDUAL_ALLOWANCE * beyond_v[:, None] / term, np.where(beyond_v[:, None] > 0,
                                                                                         np.inf, 0.0))


def stop_flags(variant: Variant, classifier: ValveClassifier, fit: PeriodFit, periods: int, centres: np.ndarray,
               half_widths: np.ndarray, noise_v: float,
               reference_condition: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The stop rule per test, vectorised (the loop's :class:`EarlyStop` and the batch study use it alike).

    Returns
    -------
    (misfit, trusted, certain, verdicts)
        The model does not fit (stop: INVALID); the fit is settled, conditioned and fitting after enough periods
        (the judgement would trust it); and, trusted, the verdict is the same over the whole box (stop); the
        verdict at each box's centre ("" where no test was trusted: the classifier is not asked then).
    """
    misfit = judges_model_fit(variant, periods, fit) & ~model_fits(variant, fit, noise_v)
    problems = trust_problems(variant.acceptance, periods=periods, settled=fit.settled, misfit=misfit,
                              condition_number=judged_condition_number(reference_condition, fit.condition_number))
    trusted = problems == 0
    if not trusted.any():  # the loop's check before the fit settles: no classifier call in that tick
        return misfit, trusted, trusted.copy(), np.full(len(centres), "", dtype=object)
    same, verdicts = certain_verdicts(classifier, centres, half_widths, with_verdicts=True)
    return misfit, trusted, trusted & same, verdicts


def certain_verdicts(classifier: ValveClassifier, centres: np.ndarray, half_widths: np.ndarray, *,
                     with_verdicts: bool = False) -> np.ndarray | tuple[np.ndarray, np.ndarray]:
    """For N boxes of relative features (centres and half-widths (N, 2)): the same verdict at centre and corners.

    The batch path's form of :meth:`EarlyStop.check`'s test (one classifier call for all valves). With
    ``with_verdicts``, also the verdict at each centre.
    """
    signs = np.array([[0, 0], [-1, -1], [-1, 1], [1, -1], [1, 1]], dtype=float)
    points = centres[:, None, :] + signs[None, :, :] * half_widths[:, None, :]
    finite = np.all(np.isfinite(points), axis=(1, 2))
    points = np.where(np.isfinite(points), points, 1.0)
    verdicts = classifier.verdicts(points.reshape(-1, 2))
    verdicts = verdicts.reshape(len(centres), 5)
    same = finite & np.all(verdicts == verdicts[:, :1], axis=1)
    return (same, verdicts[:, 0]) if with_verdicts else same
