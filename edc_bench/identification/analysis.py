"""After a test: its identification and how far to trust it. Pure numpy on the trace.

- parameters: the period fit (:mod:`edc_bench.identification.period_fit`), least
  squares over the whole excitation periods in the trace;
- converged: at least ``acceptance.min_periods`` periods, and no drift (af
  and a1 of the first half of the periods and of the second half agree
  within ``settle_band_rel``);
- model fit: the part of the residual that repeats from period to period
  against the noise the position sensor causes, and the solenoid's gain
  variation, each against its limit; the whole residual and the spread of
  af and a1 from period to period are recorded beside them
  (:class:`ModelFit`);
- conditioning: condition number of the reference's regressors over the
  steady excitation (columns scaled to unit norm: collinearity of the
  excitation, not units), or the fit's own if larger;
- uncertainty: standard error of the mean over the periods (at least the
  least-squares one);
- settle times of the online estimates (informational).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from edc_bench.config.models import PARAMETER_NAMES, Variant
from edc_bench.control.design import ControllerDesign
from edc_bench.control.fel import FelController
from edc_bench.identification.period_fit import (
    GAIN_TERMS,
    FitSetup,
    PeriodFit,
    expected_drive_noise_v,
    reference_condition_number,
    solve,
    trace_blocks,
)
from edc_bench.identification.sections import ModelFitSummary
from edc_bench.identification.trust import judged_condition_number


@dataclass(frozen=True)
class ModelFit:
    """How well the feedforward model explains the drive (docs/method.md, "Model fit").

    Attributes
    ----------
    residual_rms_v : float
        What the fitted model leaves unexplained of the drive (V rms).
    expected_noise_v : float
        What the position sensor's noise alone leaves, through the PID (V rms).
    residual_ratio : float
        Their ratio: about 1 when the model explains all but the sensor noise; a CAN adapter's timing jitter and
        other noise raise it (through a USB adapter 3-7).
    systematic_rms_v : float
        The part of the residual that repeats from one excitation period to the next (V rms): the model's misfit.
        Noise, never the same twice, drops out of it; it is what the model-fit limit judges.
    systematic_ratio : float
        That against the sensor noise (``expected_noise_v``).
    spread_rel : dict
        ``af``, ``a1``: standard deviation of the estimates from one excitation period to the next, relative.
    gain_variation_rel : float
        The solenoid's force constant's variation over the swing (+/-, relative), as identified.
    problems : list of str
        What does not fit (empty when the model fits), each with the measured figure and its limit.
    core_shift_rel : dict
        ``af``, ``a1``: the fit over every used row's distance from the estimate (the core rows' fit), relative
        to the estimate (:attr:`~edc_bench.identification.period_fit.PeriodFit.core_shift`): what the model misses
        at reversals.
    """

    residual_rms_v: float
    expected_noise_v: float
    residual_ratio: float
    spread_rel: dict[str, float]
    gain_variation_rel: float
    problems: list[str]
    systematic_rms_v: float = math.nan
    systematic_ratio: float = math.nan
    core_shift_rel: dict[str, float] | None = None

    @property
    def fits(self) -> bool:
        """True when no measure is beyond its limit."""
        return not self.problems

    def summary(self) -> ModelFitSummary:
        """The model fit as the record keeps it: every figure under its own name, and whether it fits."""
        return ModelFitSummary.model_validate(self, from_attributes=True)


def model_fit_line(fit: ModelFit, ratio_decimals: int = 2) -> str:
    """The model fit in one line for people: the residual against the sensor noise, the part of it the same every
    period, the estimates' spread from period to period, the solenoid gain's variation.

    A figure the test did not measure (with one whole period, the part the same every period and the spread) is
    left out, never printed as ``nan``.
    """
    d = ratio_decimals
    line = f"residual {fit.residual_ratio:.{d}f}x the sensor noise"
    if math.isfinite(fit.systematic_ratio):
        line += f" ({fit.systematic_ratio:.{d}f}x the same every period)"
    spread = [f"{name} {fit.spread_rel[name]:.1%}" for name in ("af", "a1")
              if fit.spread_rel.get(name) is not None and math.isfinite(fit.spread_rel[name])]
    line += (", period-to-period spread " + " ".join(spread)) if spread else ", no period-to-period spread (one period)"
    return line + f", solenoid gain variation +/-{fit.gain_variation_rel:.0%}"


@dataclass(frozen=True)
class Identification:
    """Quality figures of one identification.

    ``final``, ``std``, ``condition_number``, ``residual_rms_v`` and ``model_fit`` are the period fit's
    (:mod:`edc_bench.identification.period_fit`); ``settle_s`` are the online estimator's settle times, for the record.
    """

    final: dict[str, float]
    std: dict[str, float]
    settle_s: dict[str, float]
    converged: bool
    condition_number: float
    samples_used: int
    residual_rms_v: float
    periods: int = 0
    period_s: float = 0.0
    settled: bool = False
    model_fit: ModelFit | None = None
    nuisance: dict[str, float] | None = None
    #: periods with rows enough for their own estimate: fewer than :attr:`periods` where a period's rows were left
    #: out (host stalls, missing replies, a rack that did not slide)
    periods_estimated: int = 0


def settle_times_s(t_s: np.ndarray, values: np.ndarray, start_s: float, band_rel: float) -> np.ndarray:
    """Time from ``start_s`` after which each column of ``values`` stays within ``band_rel`` of its last value.

    Parameters
    ----------
    t_s : numpy.ndarray
        (T,) sample times.
    values : numpy.ndarray
        (T,) or (T, n): one estimate's history per column (the batch path
        passes one column per valve).
    start_s : float
        When the estimation started.
    band_rel : float
        The settle band, relative to the final value.

    Returns
    -------
    numpy.ndarray
        () or (n,) settle times; inf where the last sample is itself outside
        (never settled), 0 where it never left the band.
    """
    values = np.asarray(values, dtype=float)
    if len(values) == 0:
        return np.full(values.shape[1:], math.inf)
    final = values[-1]
    outside = np.abs(values - final) > band_rel * np.maximum(np.abs(final), 1e-12)
    rows = len(values)
    last_out = np.where(outside.any(axis=0), rows - 1 - np.argmax(outside[::-1], axis=0), -1)
    after = np.asarray(t_s, dtype=float)[np.minimum(last_out + 1, rows - 1)]
    return np.where(last_out < 0, 0.0, np.where(last_out == rows - 1, math.inf, np.maximum(0.0, after - start_s)))


def model_fit_failures(variant: Variant, fit: PeriodFit, expected_noise_v: float) -> dict[str, np.ndarray]:
    """Per model-fit measure, per test: beyond the variant's limit (NaN counts as beyond). Vectorised over tests.

    The residual is judged by its part that repeats from period to period (:func:`~edc_bench.identification.period_fit.
    solve`): noise (the sensor's, an adapter's timing jitter) raises the whole residual and the period-to-period
    spread without biasing af or a1, and widens their uncertainty, which the verdict takes into account.
    """
    acc = variant.acceptance
    ratio = (fit.systematic_rms_v / expected_noise_v if expected_noise_v > 0
             else np.full_like(fit.systematic_rms_v, np.inf))
    return {
        "residual": ~(ratio <= acc.max_residual_ratio),
        "gain": ~(fit.gain_variation_rel <= acc.max_gain_variation_rel),
    }


def model_fits(variant: Variant, fit: PeriodFit, expected_noise_v: float) -> np.ndarray:
    """Per test: no model-fit measure beyond its limit."""
    return ~np.any(np.stack(list(model_fit_failures(variant, fit, expected_noise_v).values())), axis=0)


def model_fit_problems(variant: Variant, fit: PeriodFit, expected_noise_v: float) -> list[str]:
    """What in ``fit`` (one test) is beyond the variant's model-fit limits, each with figure and limit."""
    acc = variant.acceptance
    failed = {name: bool(flags[0]) for name, flags in model_fit_failures(variant, fit, expected_noise_v).items()}
    out = []
    if failed["residual"]:
        systematic = float(fit.systematic_rms_v[0])
        ratio = systematic / expected_noise_v if expected_noise_v > 0 else math.inf
        out.append(f"it leaves {systematic * 1e3:.1f} mV rms of the drive unexplained the same way in every "
                   f"excitation period, {ratio:.1f}x the sensor noise (limit {acc.max_residual_ratio:g}x)")
    if failed["gain"]:
        out.append(f"the solenoid's force constant varies about +/-{float(fit.gain_variation_rel[0]):.0%} over the "
                   f"swing (the model's correction holds to +/-{acc.max_gain_variation_rel:.0%})")
    return out


def judges_model_fit(variant: Variant, periods: int | np.ndarray, fit: PeriodFit) -> np.ndarray:
    """Where the model fit is judged: enough periods (``acceptance.min_periods``), that many with their own
    estimate. The judgement, the early stop and the batch path ask this one rule."""
    need = variant.acceptance.min_periods
    return (np.asarray(periods) >= need) & (np.asarray(fit.periods_used) >= need)


def analyse(trace: dict[str, np.ndarray], controller: FelController, variant: Variant) -> Identification:
    """Quality figures of the identification in ``trace``.

    The parameters, their uncertainty, the conditioning and the model fit are the period fit's
    (:mod:`edc_bench.identification.period_fit`) over the whole excitation periods in the trace; the settle
    times are the online estimator's.

    Parameters
    ----------
    trace : dict of numpy.ndarray
        The filled trace columns.
    controller : FelController
        The controller that ran (its reference and parameter split).
    variant : Variant
        For the acceptance settings.
    """
    acc = variant.acceptance
    t = trace["t_s"]
    start = variant.excitation.move_s
    settle = {n: float(settle_times_s(t, trace[f"{n}_hat"], start, acc.settle_band_rel))
              for n in (PARAMETER_NAMES[i] for i in controller.estimated)}
    setup = FitSetup.from_variant(variant)
    blocks, periods = trace_blocks(setup, trace, reference_resistance_ohm=variant.coil.resistance_ohm)
    fit = solve(blocks, periods, acc.settle_band_rel)
    final = {n: float(trace[f"{n}_hat"][-1]) if len(t) else math.nan for n in PARAMETER_NAMES}
    std = {n: math.nan for n in PARAMETER_NAMES}
    for i in controller.fixed:
        final[PARAMETER_NAMES[i]] = controller.nominal[i]
        std[PARAMETER_NAMES[i]] = 0.0
    period_s = setup.block_ticks * setup.period_s
    if fit is None:
        return Identification(final, std, settle, False, math.inf, 0, math.nan, 0, period_s)
    # identifiability is the excitation's (the trajectory's incidental harmonics would make a single sine look
    # identifiable), or the fit's where that is worse: the trust rule's one definition
    cond = float(judged_condition_number(reference_condition_number(ControllerDesign.from_variant(variant)),
                                         fit.condition_number[0]))
    for name in (PARAMETER_NAMES[i] for i in controller.estimated):
        final[name] = float(fit.value(name)[0])
        std[name] = float(fit.std_of(name)[0])
    noise = expected_drive_noise_v(variant)
    model_fit = ModelFit(
        residual_rms_v=float(fit.residual_rms_v[0]), expected_noise_v=noise,
        residual_ratio=float(fit.residual_rms_v[0]) / noise if noise > 0 else math.inf,
        systematic_rms_v=float(fit.systematic_rms_v[0]),
        systematic_ratio=float(fit.systematic_rms_v[0]) / noise if noise > 0 else math.inf,
        spread_rel={n: float(fit.spread_rel[n][0]) for n in ("af", "a1")},
        gain_variation_rel=float(fit.gain_variation_rel[0]),
        core_shift_rel={n: float(fit.relative_figures(n)[1][0]) for n in ("af", "a1")},
        # judged on periods that have their own estimate: a fit left without rows (a PC that stalled through
        # them) has no figures to judge, only too few periods
        problems=model_fit_problems(variant, fit, noise) if judges_model_fit(variant, periods, fit).all() else [],
    )
    settled = bool(fit.settled[0])
    converged = settled and periods >= acc.min_periods
    nuisance = {name: float(fit.value(name)[0]) for name in GAIN_TERMS}
    return Identification(final, std, settle, converged, cond, int(fit.samples[0]),
                          float(fit.residual_rms_v[0]), periods, period_s, settled, model_fit, nuisance,
                          int(fit.periods_used[0]))
