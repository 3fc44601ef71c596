"""Discrete PID on the rack error, with derivative filter, anti-windup and
output limits. Pure: the caller supplies the error and the period."""

from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class PidGains:
    """Gains of the feedback controller.

    Attributes
    ----------
    kp_v_per_mm : float
        Proportional gain.
    ki_v_per_mm_s : float
        Integral gain.
    kd_v_s_per_mm : float
        Derivative gain (on the error, filtered).
    derivative_filter_hz : float
        Corner frequency of the first-order derivative filter.
    """

    kp_v_per_mm: float
    ki_v_per_mm_s: float
    kd_v_s_per_mm: float
    derivative_filter_hz: float


def derivative_filter_coefficients(gains: PidGains, period_s: float) -> tuple[float, float]:
    """Coefficients ``(a, b)`` of the backward-Euler filtered derivative ``d_k = a d_{k-1} + b (e_k - e_{k-1})``.

    The one discretisation of the derivative: the PID, its vectorised twin in
    the batch path and the gain check's loop model all take it from here.
    """
    tau = 1.0 / (2.0 * math.pi * gains.derivative_filter_hz)
    return tau / (tau + period_s), gains.kd_v_s_per_mm / (tau + period_s)


class Pid:
    """Parallel PID: ``u = kp e + ki int(e) + kd D(e)``, D a filtered derivative.

    The integrator is held (conditional integration) whenever the total drive
    saturates in the direction the integrator would push it further, so it
    never winds up while the amplifier is at its limit.

    Parameters
    ----------
    gains : PidGains
        The gains.
    period_s : float
        Sampling period.
    output_limit_v : float
        The PID's own output is clipped to +/- this.
    """

    def __init__(self, gains: PidGains, period_s: float, output_limit_v: float) -> None:
        self.gains = gains
        self.period_s = period_s
        self.output_limit_v = output_limit_v
        self._a, self._b = derivative_filter_coefficients(gains, period_s)
        self.integral_v = 0.0
        self.derivative_v = 0.0
        self._last_error: float | None = None
        self.proportional_v = 0.0
        self.output_v = 0.0

    def restart_derivative(self) -> None:
        """Forget the last error, so the next update takes no derivative across a gap in the samples."""
        self._last_error = None

    def update(self, error_mm: float, saturated_sign: int = 0) -> float:
        """One PID step.

        Parameters
        ----------
        error_mm : float
            Reference minus measured rack position.
        saturated_sign : int, optional
            +1 if the previous total drive was at its upper limit, -1 at its
            lower limit, 0 otherwise (for anti-windup).

        Returns
        -------
        float
            PID output in V, within +/- ``output_limit_v``.
        """
        g = self.gains
        self.proportional_v = g.kp_v_per_mm * error_mm
        step = g.ki_v_per_mm_s * error_mm * self.period_s
        if not (saturated_sign > 0 and step > 0.0) and not (saturated_sign < 0 and step < 0.0):
            self.integral_v += step
        last = self._last_error
        if last is not None:
            self.derivative_v = self._a * self.derivative_v + self._b * (error_mm - last)
        self._last_error = error_mm
        limit = self.output_limit_v
        # the integrator alone never exceeds the limit either
        if self.integral_v > limit:
            self.integral_v = limit
        elif self.integral_v < -limit:
            self.integral_v = -limit
        u = self.proportional_v + self.integral_v + self.derivative_v
        self.output_v = limit if u > limit else (-limit if u < -limit else u)
        return self.output_v
