"""Discrete PID on the rack error, with derivative filter, anti-windup and
output limits. Pure: the caller supplies the error and the period."""

from __future__ import annotations

import math
from dataclasses import dataclass

from edc_bench.control import law


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


class Pid:
    """Parallel PID: ``u = kp e + ki int(e) + kd D(e)``, D a filtered derivative.

    The integrator is held (conditional integration) whenever the total drive
    saturates in the direction the integrator would push it further, so it
    never winds up while the amplifier is at its limit. The arithmetic is
    :func:`edc_bench.control.law.pid_update`'s, shared with the batch path.

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
        self.coefficients = law.PidCoefficients.of(gains, period_s, output_limit_v)
        self.state = law.PidState()

    @property
    def integral_v(self) -> float:
        """The integrator's share of the output."""
        return self.state.integral_v

    @property
    def derivative_v(self) -> float:
        """The filtered derivative's share."""
        return self.state.derivative_v

    @property
    def proportional_v(self) -> float:
        """The proportional share at the last update."""
        return self.state.proportional_v

    @property
    def output_v(self) -> float:
        """The last output."""
        return self.state.output_v

    def restart_derivative(self) -> None:
        """Forget the last error, so the next update takes no derivative across a gap in the samples."""
        self.state.last_error_mm = math.nan

    def update(self, error_mm: float, saturated_sign: int = 0, usable: bool = True) -> float:
        """One PID step.

        Parameters
        ----------
        error_mm : float
            Reference minus measured rack position.
        saturated_sign : int, optional
            +1 if the previous total drive was at its upper limit, -1 at its
            lower limit, 0 otherwise (for anti-windup).
        usable : bool, optional
            False when no sample is young enough to be used: the PID holds its output and its state.

        Returns
        -------
        float
            PID output in V, within +/- ``output_limit_v``.
        """
        return law.pid_update(law.SCALAR, self.coefficients, self.state, error_mm, saturated_sign, usable)
