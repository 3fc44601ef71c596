"""Online estimators of the feedforward parameters, behind one interface.

Both fit ``y = w . theta`` one sample at a time, where ``w`` are normalised
regressors (reference signals only, so sensor noise does not bias the fit)
and ``y`` is the drive actually applied (feedback-error learning: when
``theta`` is right, the PID's share ``y - w . theta`` goes to zero).

- :class:`RecursiveLeastSquares` (default): exponential forgetting, with a
  covariance from which parameter uncertainty follows.
- :class:`NormalisedGradient`: the paper's gradient law (eq. 14), with a gain
  per parameter and normalisation by ``1 + |w|^2``.

The arithmetic is :mod:`edc_bench.control.law`'s, shared with the batch
path; here in plain Python floats (for five or six parameters faster than
numpy calls). Non-finite input is refused (the update is skipped and
counted), so the estimate never becomes NaN.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections.abc import Sequence

from edc_bench.control import law

#: Bound on the RLS covariance's trace: guards against wind-up while the excitation is poor.
MAX_COVARIANCE_TRACE = 1e6


class Estimator(ABC):
    """Fits ``y = w . theta`` online.

    Parameters
    ----------
    theta0 : sequence of float
        Initial (normalised) parameters.
    """

    def __init__(self, theta0: Sequence[float]) -> None:
        self.theta = [float(v) for v in theta0]
        self.n = len(self.theta)
        self.updates = 0
        self.rejected = 0
        self.residual_var = 0.0  # exponentially weighted mean of squared a-priori errors
        self._residual_weight = 0.0

    def update(self, w: list[float], y: float) -> float:
        """Move the estimate towards explaining ``y`` by ``w`` (a list of floats, one per estimated parameter).

        Returns
        -------
        float
            The a-priori error ``y - w . theta`` (0 if the sample was refused).
        """
        err, ok = self._update(w, y)
        if not ok:
            self.rejected += 1
            return 0.0
        self.updates += 1
        # residual variance with a ~2000-sample memory
        self._residual_weight = 0.9995 * self._residual_weight + 1.0
        self.residual_var += (err * err - self.residual_var) / self._residual_weight
        return err

    @abstractmethod
    def _update(self, w: list[float], y: float) -> tuple[float, bool]:
        """Apply one update (:mod:`edc_bench.control.law`); the a-priori error and whether it applied."""

    def std(self) -> list[float] | None:
        """Standard deviation of each (normalised) parameter, if the method knows it."""
        return None


class RecursiveLeastSquares(Estimator):
    """RLS with exponential forgetting (:func:`edc_bench.control.law.rls_update`).

    Parameters
    ----------
    theta0 : sequence of float
        Initial normalised parameters.
    initial_std : sequence of float
        Prior standard deviation of each normalised parameter (P0 = diag(std^2)).
    forgetting_factor : float
        lambda in (0, 1]; memory of about 1 / (1 - lambda) samples.
    max_trace : float, optional
        Bound on trace(P): guards against covariance wind-up.
    """

    def __init__(self, theta0: Sequence[float], initial_std: Sequence[float], forgetting_factor: float,
                 max_trace: float = MAX_COVARIANCE_TRACE) -> None:
        super().__init__(theta0)
        if not 0.0 < forgetting_factor <= 1.0:
            raise ValueError("forgetting_factor must be in (0, 1]")
        self.lam = forgetting_factor
        self.max_trace = max_trace
        self.P = [[(s * s if i == j else 0.0) for j, s in enumerate(initial_std)] for i in range(len(initial_std))]

    def _update(self, w: list[float], y: float) -> tuple[float, bool]:
        return law.rls_update(law.SCALAR, self.theta, self.P, w, y, self.lam, self.max_trace)

    def std(self) -> list[float]:
        """Parameter standard deviations: sqrt(sigma^2 P_ii), sigma^2 from the residuals."""
        sigma2 = self.residual_var
        return [math.sqrt(max(self.P[i][i], 0.0) * sigma2) for i in range(self.n)]


class NormalisedGradient(Estimator):
    """The paper's gradient law (eq. 14), normalised, one gain per parameter
    (:func:`edc_bench.control.law.gradient_update`).

    ``theta += T * gamma_i * w_i * err / (1 + |w|^2)``

    Parameters
    ----------
    theta0 : sequence of float
        Initial normalised parameters.
    gains : sequence of float
        Adaptation gain per normalised parameter (1/s).
    period_s : float
        Sampling period T.
    """

    def __init__(self, theta0: Sequence[float], gains: Sequence[float], period_s: float) -> None:
        super().__init__(theta0)
        if len(gains) != self.n:
            raise ValueError("one gain per parameter")
        self.gains = [float(g) * period_s for g in gains]

    def _update(self, w: list[float], y: float) -> tuple[float, bool]:
        return law.gradient_update(law.SCALAR, self.theta, self.gains, w, y)
