"""Stop a test as soon as its verdict is known: after each whole excitation period, is it?

A test may stop once, after at least ``acceptance.min_periods`` whole periods
(:mod:`edc_bench.diagnosis.period_fit`):

- **the verdict is certain**: the fit has settled, its regression is well
  conditioned, the model fits, and the verdict at af and a1 is the same at
  every corner of their ``verdict_confidence`` interval (relative to the
  baseline, standard errors of the mean over the periods); or
- **the model does not fit**: a longer test will not help.

Otherwise the test runs on, up to the variant's duration. Before each period
ends, :attr:`EarlyStop.expected_end_s` says when the test is expected to end:
the first period at which the interval, shrinking as 1/sqrt(periods), would
leave the verdict unchanged.

The loop calls :meth:`EarlyStop.check` at the ticks in
:attr:`EarlyStop.check_ticks` (bench layer: :func:`edc_bench.bench.run_bench_test`);
the rows of one period are fed at a time, so a check costs a few
milliseconds however long the test has run.
"""

from __future__ import annotations

from statistics import NormalDist
from typing import Any

import numpy as np

from edc_bench.config.models import PARAMETER_NAMES, Variant
from edc_bench.control.design import ControllerDesign
from edc_bench.diagnosis.baseline import Baseline
from edc_bench.diagnosis.classifier import ValveClassifier
from edc_bench.diagnosis.identification import model_fit_failures, model_fit_problems
from edc_bench.diagnosis.period_fit import (
    BlockAccumulator,
    FitSetup,
    PeriodFit,
    accumulate,
    expected_drive_noise_v,
    reference_condition_number,
    rows,
    solve,
)
from edc_bench.physics.coil import inductive_shares, referred_from_estimate

#: The reasons a test ends, as records give them.
VERDICT_CERTAIN, MODEL_DOES_NOT_FIT, FULL_LENGTH, ABORTED = ("verdict certain", "model does not fit", "full length",
                                                             "aborted")


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
        #: tick -> whole periods the trace holds once that tick has its sample
        self.check_ticks = {setup.end_tick(b): b for b in range(1, self.max_periods + 1)}
        self.duration_s = ticks * setup.period_s
        self.expected_end_s = setup.end_s(min(variant.acceptance.min_periods, self.max_periods))
        self.fed = 0
        self._r_ref = variant.coil.resistance_ohm
        self._inductive = inductive_shares(variant)
        self._noise_v = expected_drive_noise_v(variant)
        self._reference_condition = reference_condition_number(ControllerDesign.from_variant(variant))
        self._z = interval_z(variant)
        self._base = np.array([baseline.af_v, baseline.a1_v_s_per_mm])

    def _feed(self, periods: int, columns: dict[str, np.ndarray]) -> None:
        """Add the rows of periods ``fed .. periods - 1`` from the trace's columns."""
        s, half = self.setup, self.setup.window // 2
        lo = s.first_tick + self.fed * s.block_ticks - half
        sl = slice(lo, s.end_tick(periods) + 1)
        rho = columns["coil_resistance_ohm"][sl] / self._r_ref
        valid = columns["reply_ok"][sl].astype(bool) & ~columns["gap"][sl].astype(bool)
        X, y, use = rows(s, columns["position_mm"][sl], columns["drive_v"][sl], rho,
                         columns["reference_velocity_mm_s"][sl], valid)
        accumulate(s, self.acc, lo, X, y, use)
        self.fed = periods

    def check(self, k: int, columns: dict[str, np.ndarray]) -> dict[str, Any] | None:
        """At tick ``k`` (one of :attr:`check_ticks`): the reason to stop now, with its figures, or None."""
        periods = self.check_ticks[k]
        self._feed(periods, columns)
        acc, setup = self.variant.acceptance, self.setup
        fit = solve(self.acc, periods, acc.settle_band_rel)
        if periods < acc.min_periods or fit is None:
            self.expected_end_s = setup.end_s(min(acc.min_periods, self.max_periods))
            return None
        parameters = np.array([[referred_from_estimate(self._inductive[PARAMETER_NAMES.index(name)],
                                                       float(fit.value(name)[0]), self._r_ref,
                                                       float(columns["coil_resistance_ohm"][k]))
                                for name in ("af", "a1")]])
        centre, half_width = relative_box(parameters, fit, self._base, self._z)
        misfit, trusted, certain = stop_flags(self.variant, self.classifier, fit, periods, centre, half_width,
                                              self._noise_v, self._reference_condition)
        time_s = setup.end_s(periods)
        if misfit[0]:
            return {"reason": MODEL_DOES_NOT_FIT, "time_s": time_s, "periods": periods,
                    "problems": model_fit_problems(self.variant, fit, self._noise_v)}
        if certain[0]:
            verdicts, _, _ = self.classifier.classify_many(centre)
            return {"reason": VERDICT_CERTAIN, "time_s": time_s, "periods": periods, "verdict": str(verdicts[0]),
                    "confidence": acc.verdict_confidence,
                    "features_rel": {"af": float(centre[0, 0]), "a1": float(centre[0, 1])},
                    "half_width_rel": {"af": float(half_width[0, 0]), "a1": float(half_width[0, 1])}}
        if not trusted[0]:  # not settled or conditioned yet: at the next period at the earliest
            self.expected_end_s = setup.end_s(min(periods + 1, self.max_periods))
            return None
        # when would the interval, shrinking as 1 / sqrt(periods), leave the verdict alone? (one classifier call)
        more = np.arange(periods + 1, self.max_periods + 1)
        boxes = certain_verdicts(self.classifier, np.repeat(centre, len(more), axis=0),
                                 half_width * np.sqrt(periods / more)[:, None])
        self.expected_end_s = setup.end_s(int(more[np.argmax(boxes)])) if boxes.any() else self.duration_s
        return None


def interval_z(variant: Variant) -> float:
    """Standard errors either side of an estimate for the variant's ``verdict_confidence`` (normal)."""
    return NormalDist().inv_cdf(0.5 + variant.acceptance.verdict_confidence / 2.0)


def relative_box(parameters: np.ndarray, fit: PeriodFit, base: np.ndarray, z: float) -> tuple[np.ndarray, np.ndarray]:
    """af and a1 relative to the baseline, and z standard errors of each: (N, 2) each.

    ``parameters``: (N, 2) af and a1 referred to the reference coil; ``base``: the baseline's af and a1.
    """
    std = np.column_stack([fit.std_of("af"), fit.std_of("a1")])
    return parameters / base, z * std / np.abs(base)


def stop_flags(variant: Variant, classifier: ValveClassifier, fit: PeriodFit, periods: int, centres: np.ndarray,
               half_widths: np.ndarray, noise_v: float,
               reference_condition: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The stop rule per test, vectorised (the loop's :class:`EarlyStop` and the batch study use it alike).

    Returns
    -------
    (misfit, trusted, certain)
        The model does not fit (stop: INVALID); the fit is settled, conditioned and fitting after enough periods
        (the judgement would trust it); and, trusted, the verdict is the same over the whole box (stop).
    """
    acc = variant.acceptance
    enough = periods >= acc.min_periods
    failures = model_fit_failures(variant, fit, noise_v)
    misfit = enough & np.any(np.stack(list(failures.values())), axis=0)
    condition = np.maximum(fit.condition_number, reference_condition)
    trusted = enough & fit.settled & ~misfit & (condition <= acc.max_condition_number)
    certain = trusted & certain_verdicts(classifier, centres, half_widths)
    return misfit, trusted, certain


def certain_verdicts(classifier: ValveClassifier, centres: np.ndarray, half_widths: np.ndarray) -> np.ndarray:
    """For N boxes of relative features (centres and half-widths (N, 2)): the same verdict at centre and corners.

    The batch path's form of :meth:`EarlyStop.check`'s test (one classifier call for all valves).
    """
    signs = np.array([[0, 0], [-1, -1], [-1, 1], [1, -1], [1, 1]], dtype=float)
    points = centres[:, None, :] + signs[None, :, :] * half_widths[:, None, :]
    finite = np.all(np.isfinite(points), axis=(1, 2))
    points = np.where(np.isfinite(points), points, 1.0)
    verdicts, _, _ = classifier.classify_many(points.reshape(-1, 2))
    verdicts = verdicts.reshape(len(centres), 5)
    return finite & np.all(verdicts == verdicts[:, :1], axis=1)
