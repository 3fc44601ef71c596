"""After a test: how far to trust its numbers. Pure numpy on the trace.

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
from edc_bench.control.fel import FelController


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


def settle_time_s(t_s: np.ndarray, values: np.ndarray, start_s: float, band_rel: float) -> float:
    """Time from ``start_s`` after which ``values`` stay within ``band_rel`` of the last value."""
    if len(values) == 0:
        return math.inf
    final = values[-1]
    outside = np.abs(values - final) > band_rel * max(abs(final), 1e-12)
    idx = np.nonzero(outside)[0]
    if len(idx) == 0:
        return 0.0
    if idx[-1] == len(values) - 1:
        return math.inf
    return max(0.0, float(t_s[idx[-1] + 1]) - start_s)


def regressors(controller: FelController, t_s: np.ndarray, period_s: float) -> np.ndarray:
    """The six regressors at the middle of each tick (as the controller used them)."""
    r, r1, r2, r3 = controller.reference.tabulate(np.asarray(t_s, dtype=float) + 0.5 * period_s)
    return np.column_stack((r3, r2, r1, r, np.ones_like(r), np.sign(r1)))


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
    settle = {n: settle_time_s(t, trace[f"{n}_hat"], start, acc.settle_band_rel)
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
        phi_all = regressors(controller, t[mask], variant.controller.period_s)
        est = list(controller.estimated)
        fixed = list(controller.fixed)
        nominal = np.array(controller.nominal)
        y_all = trace["drive_v"][mask] - phi_all[:, fixed] @ nominal[fixed]
        phi = phi_all[:, est]
        # conditioning over the steady excitation: the fade-in transient would mask collinearity
        steady = t[mask] >= start + variant.excitation.fade_s
        phi_s = phi[steady] if steady.sum() > len(est) else phi
        norms = np.linalg.norm(phi_s, axis=0)
        norms[norms == 0] = 1.0
        cond = float(np.linalg.cond((phi_s / norms).T @ (phi_s / norms)))
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


def timing_summary(trace: dict[str, np.ndarray], period_s: float) -> dict[str, float]:
    """Lateness percentiles (us) and overrun count of the ticks."""
    late = trace["lateness_s"]
    if len(late) == 0:  # the same keys, so a record's timing always reads the same way
        return {"ticks": 0, "lateness_p50_us": math.nan, "lateness_p99_us": math.nan, "lateness_p999_us": math.nan,
                "lateness_max_us": math.nan, "overruns": 0}
    q = np.percentile(late, [50, 99, 99.9]) * 1e6
    return {
        "ticks": int(len(late)),
        "lateness_p50_us": float(q[0]),
        "lateness_p99_us": float(q[1]),
        "lateness_p999_us": float(q[2]),
        "lateness_max_us": float(late.max() * 1e6),
        "overruns": int((late > period_s).sum()),
    }
