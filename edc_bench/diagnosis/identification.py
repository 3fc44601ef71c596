"""After a test: how far to trust its identification. Pure numpy on the trace.

- settle time of each parameter: from the start of the excitation until it
  stays within ``settle_band_rel`` of its final value;
- converged: af and a1 stayed in that band through the last
  ``convergence_window_s``;
- conditioning: condition number of the normalised information matrix of
  the regression (columns scaled to unit norm, so it measures collinearity
  of the regressors, not their units);
- uncertainty: least-squares standard deviation of each estimated parameter
  from the data of the last window (sigma^2 (W^T W)^-1), the same for both
  estimators.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from edc_bench.config.models import PARAMETER_NAMES, Variant
from edc_bench.control.fel import FelController, condition_number, regressor_matrix


@dataclass(frozen=True)
class Identification:
    """Quality figures of one identification."""

    final: dict[str, float]
    std: dict[str, float]
    settle_s: dict[str, float]
    converged: bool
    condition_number: float
    samples_used: int
    residual_rms_v: float


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


def analyse(trace: dict[str, np.ndarray], controller: FelController, variant: Variant) -> Identification:
    """Quality figures of the identification in ``trace``.

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
    final = {n: float(trace[f"{n}_hat"][-1]) if len(t) else math.nan for n in PARAMETER_NAMES}
    start = variant.excitation.move_s
    settle = {n: float(settle_times_s(t, trace[f"{n}_hat"], start, acc.settle_band_rel))
              for n in (PARAMETER_NAMES[i] for i in controller.estimated)}
    # settled early enough to have stayed in the band for the whole last window
    remaining = (t[-1] if len(t) else 0.0) - start - acc.convergence_window_s
    converged = bool(remaining > 0 and all(settle[n] <= remaining for n in ("af", "a1")))

    std = {n: math.nan for n in PARAMETER_NAMES}
    cond = math.inf
    used = 0
    residual_rms = math.nan
    mask = trace["adapting"].astype(bool)
    if mask.sum() >= 2 * len(controller.estimated):
        phi_all = regressor_matrix(controller.reference, t[mask], variant.controller.period_s)
        est = list(controller.estimated)
        fixed = list(controller.fixed)
        nominal = np.array(controller.nominal)
        y_all = trace["drive_v"][mask] - phi_all[:, fixed] @ nominal[fixed]
        phi = phi_all[:, est]
        # conditioning over the steady excitation: the fade-in transient would mask collinearity
        steady = t[mask] >= start + variant.excitation.fade_s
        phi_s = phi[steady] if steady.sum() > len(est) else phi
        cond = condition_number(phi_s)
        # uncertainty over the last window
        window = t[mask] >= (t[-1] - acc.convergence_window_s)
        phi_w, y_w = phi[window], y_all[window]
        used = int(window.sum())
        a_final = np.array([final[PARAMETER_NAMES[i]] for i in est])
        resid = y_w - phi_w @ a_final
        if used > len(est):
            sigma2 = float(resid @ resid) / (used - len(est))
            residual_rms = math.sqrt(float(resid @ resid) / used)
            try:
                cov = sigma2 * np.linalg.inv(phi_w.T @ phi_w)
                for j, i in enumerate(est):
                    std[PARAMETER_NAMES[i]] = float(math.sqrt(max(cov[j, j], 0.0)))
            except np.linalg.LinAlgError:
                pass
    for i in controller.fixed:
        std[PARAMETER_NAMES[i]] = 0.0
    return Identification(final, std, settle, converged, cond, used, residual_rms)
