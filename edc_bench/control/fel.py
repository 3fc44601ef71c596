"""Feedback-error learning: one controller tick, pure.

Per tick k (period T, time t_k = k T), given the rack position sampled at
t_{k-1} (the rig's reply to the previous command, DESIGN 3.1):

1. error e = r(t_{k-1}) - x(t_{k-1}); PID output u2.
2. regressor W = [r''', r'', r', r, 1, sgn(r')] at t_k + T/2, the middle of
   the interval over which the drive is held (zero-order hold).
3. feedforward u1 = W . a_hat; drive u = sat(u1 + u2).
4. estimator update with target u (so its error is e2 = u - u1), skipped
   while the drive saturates, before the excitation starts, and while |r'|
   is small (stick windows at reversals are not explained by sgn(r')).

Only parameters listed as estimated are adapted; the others stay at their
nominal value and their share of u1 is taken off the target.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from edc_bench.control.estimators import Estimator
from edc_bench.control.pid import Pid
from edc_bench.control.reference import Reference

N_PARAMETERS = 6


class FelController:
    """PID feedback, friction-compensated feedforward and online estimation.

    Parameters
    ----------
    reference : Reference
        The rack reference.
    pid : Pid
        The feedback controller.
    estimator : Estimator
        Fits the estimated parameters, in normalised form.
    nominal : sequence of float
        Nominal ``[a3, a2, a1, a0, b, af]``: start values, and the values of
        the parameters that are not estimated.
    estimated : sequence of int
        Indices (into the six) of the parameters the estimator adapts, in the
        estimator's order.
    scales : sequence of float
        Typical magnitude of each regressor; the estimator works on
        ``W_i / scale_i``, so its parameters are ``a_i * scale_i``.
    drive_limit_v : float
        The drive saturates at +/- this.
    period_s : float
        Tick period T.
    adapt_from_s : float
        No adaptation before this time (the move to mid-stroke).
    reversal_speed_mm_s : float
        No adaptation while |r'| is below this.
    ticks : int, optional
        Number of ticks the test will run. The reference of those ticks is
        tabulated up front (vectorised), so a tick only looks it up; ticks
        beyond are computed as they come.
    """

    def __init__(self, reference: Reference, pid: Pid, estimator: Estimator, *, nominal: Sequence[float],
                 estimated: Sequence[int], scales: Sequence[float], drive_limit_v: float, period_s: float,
                 adapt_from_s: float, reversal_speed_mm_s: float, ticks: int = 0) -> None:
        if len(nominal) != N_PARAMETERS or len(scales) != N_PARAMETERS:
            raise ValueError("nominal and scales need six entries: a3, a2, a1, a0, b, af")
        self.reference = reference
        self.pid = pid
        self.estimator = estimator
        self.estimated = tuple(estimated)
        self.fixed = tuple(i for i in range(N_PARAMETERS) if i not in self.estimated)
        self.nominal = tuple(float(v) for v in nominal)
        self.scales = tuple(float(s) for s in scales)
        self.drive_limit_v = drive_limit_v
        self.period_s = period_s
        self.adapt_from_s = adapt_from_s
        self.reversal_speed_mm_s = reversal_speed_mm_s
        self._w = [0.0] * N_PARAMETERS
        self._w_est = [0.0] * len(self.estimated)
        self._saturated = 0
        k = np.arange(ticks, dtype=float)
        mid = reference.tabulate((k + 0.5) * period_s)  # the regressor's times
        self._table = list(zip(*mid.tolist(), reference.tabulate(k * period_s)[0].tolist(), strict=True))
        # last tick's values, for the recorder
        self.r_mm = reference.at(0.0)[0]
        self.r_prev_mm = self.r_mm
        self.r1_mm_s = 0.0
        self.u1_v = 0.0
        self.u2_v = 0.0
        self.u_v = 0.0
        self.adapting = False

    def parameters(self) -> list[float]:
        """Current ``[a3, a2, a1, a0, b, af]`` in physical units."""
        out = list(self.nominal)
        theta = self.estimator.theta
        for j, i in enumerate(self.estimated):
            out[i] = theta[j] / self.scales[i]
        return out

    def write_parameters(self, columns: Sequence, row: int) -> None:
        """Store the current parameters into ``columns[i][row]`` (i over a3..af), no list built."""
        theta, scales = self.estimator.theta, self.scales
        for j, i in enumerate(self.estimated):
            columns[i][row] = theta[j] / scales[i]
        for i in self.fixed:
            columns[i][row] = self.nominal[i]

    def step(self, k: int, measured_mm: float) -> float:
        """Compute the drive for tick ``k``.

        Parameters
        ----------
        k : int
            Tick index (time k T).
        measured_mm : float
            Rack position sampled at tick k-1.

        Returns
        -------
        float
            Drive voltage u to send, within +/- the drive limit.
        """
        T = self.period_s
        t = k * T
        error = self.r_prev_mm - measured_mm
        u2 = self.pid.update(error, self._saturated)

        if k < len(self._table):
            r, r1, r2, r3, r_now = self._table[k]
        else:
            r, r1, r2, r3 = self.reference.at(t + 0.5 * T)
            r_now = self.reference.at(t)[0]
        w = self._w
        w[0], w[1], w[2], w[3], w[4] = r3, r2, r1, r, 1.0
        w[5] = 1.0 if r1 > 0.0 else (-1.0 if r1 < 0.0 else 0.0)

        params = self.estimator.theta
        scales = self.scales
        u1 = 0.0
        for j, i in enumerate(self.estimated):
            u1 += params[j] * w[i] / scales[i]
        fixed_part = 0.0
        for i in self.fixed:
            fixed_part += self.nominal[i] * w[i]
        u1 += fixed_part

        u = u1 + u2
        limit = self.drive_limit_v
        if u >= limit:
            u, self._saturated = limit, 1
        elif u <= -limit:
            u, self._saturated = -limit, -1
        else:
            self._saturated = 0

        self.adapting = (
            self._saturated == 0 and t >= self.adapt_from_s and abs(r1) >= self.reversal_speed_mm_s
        )
        if self.adapting:
            w_est = self._w_est
            for j, i in enumerate(self.estimated):
                w_est[j] = w[i] / scales[i]
            self.estimator.update(w_est, u - fixed_part)

        # the reference at this tick is what the next sample will be compared to
        self.r_prev_mm = r_now
        self.r_mm, self.r1_mm_s, self.u1_v, self.u2_v, self.u_v = r, r1, u1, u2, u
        return u
