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
from edc_bench.diagnosis.baseline import Baseline
from edc_bench.diagnosis.classifier import ValveClassifier
from edc_bench.diagnosis.identification import model_fit_problems
from edc_bench.diagnosis.period_fit import BlockAccumulator, FitSetup, PeriodFit, accumulate, rows, solve
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
        half = setup.window // 2
        #: tick -> whole periods the trace holds once that tick has its sample
        self.check_ticks = {setup.first_tick + b * setup.block_ticks + half: b for b in range(1, self.max_periods + 1)}
        self.duration_s = ticks * setup.period_s
        acc = variant.acceptance
        self.z = NormalDist().inv_cdf(0.5 + acc.verdict_confidence / 2.0)
        self.expected_end_s = self.end_s(min(acc.min_periods, self.max_periods))
        self.fed = 0
        self._r_ref = variant.coil.resistance_ohm
        self._inductive = inductive_shares(variant)
        self._noise_v = None

    def end_s(self, periods: int) -> float:
        """When a test with ``periods`` whole periods ends (trace time)."""
        s = self.setup
        return (s.first_tick + periods * s.block_ticks + s.window // 2 + 1) * s.period_s

    def _feed(self, periods: int, columns: dict[str, np.ndarray]) -> None:
        """Add the rows of periods ``fed .. periods - 1`` from the trace's columns."""
        s, half = self.setup, self.setup.window // 2
        start = s.first_tick + self.fed * s.block_ticks
        end = s.first_tick + periods * s.block_ticks
        lo, hi = start - half, end + half + 1
        sl = slice(lo, hi)
        rho = columns["coil_resistance_ohm"][sl] / self._r_ref
        valid = columns["reply_ok"][sl].astype(bool) & ~columns["gap"][sl].astype(bool)
        X, y, use = rows(s, columns["position_mm"][sl], columns["drive_v"][sl], rho,
                         columns["reference_velocity_mm_s"][sl], valid)
        accumulate(s, self.acc, lo, X, y, use)
        self.fed = periods

    def check(self, k: int, columns: dict[str, np.ndarray]) -> dict[str, Any] | None:
        """At tick ``k`` (one of :attr:`check_ticks`): the reason to stop now, with its figures, or None."""
        from edc_bench.diagnosis.identification import expected_drive_noise_v

        periods = self.check_ticks[k]
        self._feed(periods, columns)
        acc = self.variant.acceptance
        if periods < acc.min_periods:
            self.expected_end_s = self.end_s(min(acc.min_periods, self.max_periods))
            return None
        fit = solve(self.acc, periods, acc.settle_band_rel)
        if fit is None:
            return None
        if self._noise_v is None:
            self._noise_v = expected_drive_noise_v(self.variant)
        time_s = self.end_s(periods)
        problems = model_fit_problems(self.variant, fit, self._noise_v)
        if problems:
            return {"reason": MODEL_DOES_NOT_FIT, "time_s": time_s, "periods": periods, "problems": problems}
        if not bool(fit.settled[0]) or float(fit.condition_number[0]) > acc.max_condition_number:
            self.expected_end_s = self.end_s(min(periods + 1, self.max_periods))
            return None
        coil_ohm = float(columns["coil_resistance_ohm"][k])
        centre, half_width = self._relative_box(fit, coil_ohm)
        if self._certain(centre, half_width):
            verdicts, _, _ = self.classifier.classify_many(centre[None, :])
            return {"reason": VERDICT_CERTAIN, "time_s": time_s, "periods": periods, "verdict": str(verdicts[0]),
                    "confidence": acc.verdict_confidence,
                    "features_rel": {"af": float(centre[0]), "a1": float(centre[1])},
                    "half_width_rel": {"af": float(half_width[0]), "a1": float(half_width[1])}}
        # when would the interval, shrinking as 1 / sqrt(periods), leave the verdict alone? (one classifier call)
        more = np.arange(periods + 1, self.max_periods + 1)
        certain = self._certain_many(centre, half_width[None, :] * np.sqrt(periods / more)[:, None])
        self.expected_end_s = self.end_s(int(more[np.argmax(certain)])) if certain.any() else self.duration_s
        return None

    def _relative_box(self, fit: PeriodFit, coil_ohm: float) -> tuple[np.ndarray, np.ndarray]:
        """af and a1 relative to the baseline (referred to the reference coil), and z standard errors of each."""
        base = self.baseline
        out, width = [], []
        for name, base_value in (("af", base.af_v), ("a1", base.a1_v_s_per_mm)):
            i = PARAMETER_NAMES.index(name)
            value = referred_from_estimate(self._inductive[i], float(fit.value(name)[0]), self._r_ref, coil_ohm)
            out.append(value / base_value)
            width.append(self.z * float(fit.std_of(name)[0]) / abs(base_value))
        return np.array(out), np.array(width)

    def _certain(self, centre: np.ndarray, half_width: np.ndarray) -> bool:
        """The same verdict at the centre and every corner of the box."""
        return bool(self._certain_many(centre, half_width[None, :])[0])

    def _certain_many(self, centre: np.ndarray, half_widths: np.ndarray) -> np.ndarray:
        """For each row of half-widths: the same verdict at the centre and every corner of that box."""
        if len(half_widths) == 0:
            return np.zeros(0, dtype=bool)
        signs = np.array([[0, 0], [-1, -1], [-1, 1], [1, -1], [1, 1]], dtype=float)
        points = centre[None, None, :] + signs[None, :, :] * half_widths[:, None, :]  # (boxes, 5, 2)
        finite = np.all(np.isfinite(points), axis=(1, 2))
        points = np.where(np.isfinite(points), points, 1.0)
        verdicts, _, _ = self.classifier.classify_many(points.reshape(-1, 2))
        verdicts = verdicts.reshape(len(half_widths), 5)
        return finite & np.all(verdicts == verdicts[:, :1], axis=1)


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
