"""The controller's arithmetic, written once, for one test (floats) or thousands at once (numpy arrays).

Every tick the bench computes the PID's share of the drive, the
regressors and their split into estimated and fixed parameters, the
feedforward for this coil, the saturated drive, whether the estimator may
learn from it, its target and its update (:func:`regressors`,
:func:`feedforward_tick`, :func:`estimator_target`: the tick's composition,
fixed per design by :class:`Composition`). This module is the one place
that says how. Three callers run it:

- the loop's controller (:class:`~edc_bench.control.fel.FelController`, via
  :class:`~edc_bench.control.pid.Pid` and :mod:`~edc_bench.control.estimators`),
  with :data:`SCALAR`: plain Python floats and lists, the fastest for one test;
- the batch path (:mod:`edc_bench.population.batch`), with :data:`ARRAYS`:
  each value an array over valves, each vector a (n, N) array;
- the benchmark's floor (:func:`edc_bench.perf.compute.lean_tick`), with
  :data:`SCALAR` and nothing else around it.

The functions are written in a few primitives (:class:`~edc_bench.control.scalar_ops.Ops`); each
backend implements the primitives (a dot product is a Python loop for five
floats, one ``np.add.reduce`` for five arrays, in the same order), never the controller. Callers
reach the functions through this module (``law.pid_update(...)``), so a
change here is a change everywhere.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from edc_bench.control.scalar_ops import Ops


class ArrayOps(Ops):
    """The primitives for N tests at once: a value is an (N,) array, a vector (n, N), a matrix (n, n, N)."""

    where = staticmethod(np.where)
    isnan = staticmethod(np.isnan)
    isfinite = staticmethod(np.isfinite)

    @staticmethod
    def clip(x: np.ndarray, limit: float) -> np.ndarray:
        # np.clip's Python wrapper costs several microseconds a call; this is the same for finite limits
        return np.minimum(np.maximum(x, -limit), limit)

    @staticmethod
    def any(x: np.ndarray) -> bool:
        return bool(np.any(x))

    sign = staticmethod(np.sign)

    @staticmethod
    def scaled_rows(w: np.ndarray, rows: tuple[int, ...], scales: tuple[float, ...]) -> np.ndarray:
        return w[list(rows)] * np.array(scales)[:, None]

    @staticmethod
    def weighted_rows(w: np.ndarray, weights: tuple[tuple[int, float], ...]) -> Any:
        out: Any = 0.0
        for i, a in weights:
            out = out + a * w[i]
        return out

    # The sums below add their few terms one after another, in order, as the floats' do: np.add.reduce along an
    # axis of fewer than eight terms does (numpy sums pairwise only from eight on). np.einsum orders its terms
    # by the arrays' shape, so a test alone and the same test among others differed in the last bit.
    # tests/control/test_law.py holds these to the floats' bits for one test, a few and many.
    @staticmethod
    def dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        return np.add.reduce(a * b, axis=0)

    @staticmethod
    def matvec(m: np.ndarray, v: np.ndarray) -> np.ndarray:
        return np.add.reduce(m * v[None], axis=1)

    @staticmethod
    def divide(v: np.ndarray, d: np.ndarray) -> np.ndarray:
        return v / d

    @staticmethod
    def multiply(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        return a * b

    @staticmethod
    def add_scaled(v: np.ndarray, g: np.ndarray, s: np.ndarray, ok: np.ndarray) -> None:
        if ok.all():  # the common case: in place, no copies
            v += g * s
        else:
            v[...] = np.where(ok, v + g * s, v)

    @staticmethod
    def rank_one_down(m: np.ndarray, g: np.ndarray, h: np.ndarray, scale: float, ok: np.ndarray) -> None:
        if ok.all():
            m -= g[:, None, :] * h[None, :, :]
            m *= scale
        else:
            m[...] = np.where(ok, (m - g[:, None, :] * h[None, :, :]) * scale, m)
        # the lower triangle mirrors the upper, as the floats' version keeps it (g h^T is symmetric only to
        # rounding): the same bits as one test in floats
        lower = _LOWER[len(m)]
        m[lower] = m[lower[1], lower[0]]

    @staticmethod
    def bound_trace(m: np.ndarray, max_trace: float) -> None:
        diagonal = np.arange(len(m))
        trace = np.add.reduce(m[diagonal, diagonal], axis=0)
        if np.any(trace > max_trace):
            m *= np.where(trace > max_trace, max_trace / trace, 1.0)


#: Per size n, the indices (rows, columns) of an n x n matrix's strict lower triangle.
_LOWER = {n: np.tril_indices(n, -1) for n in range(1, 9)}

#: One test, in Python floats.
SCALAR = Ops()
#: Many tests, in numpy arrays (valves along the last axis).
ARRAYS = ArrayOps()


# -- the PID -------------------------------------------------------------------------------------------------------

def derivative_filter_coefficients(gains: Any, period_s: float) -> tuple[float, float]:
    """Coefficients ``(a, b)`` of the backward-Euler filtered derivative ``d_k = a d_{k-1} + b (e_k - e_{k-1})``,
    from the gains (:class:`~edc_bench.control.pid.PidGains`: its ``kd_v_s_per_mm`` and ``derivative_filter_hz``).

    The one discretisation of the derivative: the PID, its vectorised twin in
    the batch path and the gain check's loop model all take it from here.
    """
    tau = 1.0 / (2.0 * math.pi * gains.derivative_filter_hz)
    return tau / (tau + period_s), gains.kd_v_s_per_mm / (tau + period_s)


@dataclass(frozen=True)
class PidCoefficients:
    """The PID's numbers for one period: gains, the derivative filter's coefficients, the output limit."""

    kp_v_per_mm: float
    ki_v_per_mm_s: float
    period_s: float
    derivative_a: float
    derivative_b: float
    limit_v: float

    @classmethod
    def of(cls, gains: Any, period_s: float, limit_v: float) -> PidCoefficients:
        """From the gains (:class:`~edc_bench.control.pid.PidGains`), the period and the drive limit."""
        a, b = derivative_filter_coefficients(gains, period_s)
        return cls(gains.kp_v_per_mm, gains.ki_v_per_mm_s, period_s, a, b, limit_v)


class PidState:
    """The PID's memory: integral, filtered derivative, the error it last took (NaN: none), its output.

    Each a float for one test, an (N,) array for N tests.
    """

    def __init__(self, zero: Any = 0.0) -> None:
        self.integral_v = zero * 1.0
        self.derivative_v = zero * 1.0
        self.last_error_mm = zero * math.nan
        self.proportional_v = zero * 1.0
        self.output_v = zero * 1.0

    def take(self, keep: np.ndarray) -> None:
        """Keep the tests ``keep`` (indices) of an (N,) state: a batch whose other tests have stopped."""
        for name in ("integral_v", "derivative_v", "last_error_mm", "proportional_v", "output_v"):
            setattr(self, name, getattr(self, name)[keep])


def pid_update(ops: Ops, c: PidCoefficients, s: PidState, error_mm: Any, saturated: Any, usable: Any = True) -> Any:
    """One PID step on ``error_mm`` (reference minus measured); the output, within +/- the limit.

    The integrator is held while the last drive saturated the way it pushes (``saturated``: +1, -1 or 0), and
    never exceeds the limit itself; the derivative is filtered and not taken across a missing previous error.
    Where ``usable`` is false (no sample young enough) the PID holds its output and its state.
    """
    proportional = c.kp_v_per_mm * error_mm
    step = c.ki_v_per_mm_s * error_mm * c.period_s
    integral = ops.clip(ops.where(saturated * step > 0.0, s.integral_v, s.integral_v + step), c.limit_v)
    last = s.last_error_mm
    derivative = ops.where(ops.isnan(last), s.derivative_v,
                           c.derivative_a * s.derivative_v + c.derivative_b * (error_mm - last))
    output = ops.clip(proportional + integral + derivative, c.limit_v)
    if usable is True:
        s.integral_v, s.derivative_v, s.last_error_mm = integral, derivative, error_mm
        s.proportional_v, s.output_v = proportional, output
    else:
        s.integral_v = ops.where(usable, integral, s.integral_v)
        s.derivative_v = ops.where(usable, derivative, s.derivative_v)
        s.last_error_mm = ops.where(usable, error_mm, last)
        s.proportional_v = ops.where(usable, proportional, s.proportional_v)
        s.output_v = ops.where(usable, output, s.output_v)
    return s.output_v


# -- the tick's composition: regressors, their split, the feedforward, the drive, the estimator's target -------

@dataclass(frozen=True)
class Composition:
    """What a controller design fixes of how each tick is composed (built by
    :meth:`~edc_bench.control.design.ControllerDesign.composition`, the same for the loop, the batch path and the
    benchmark's floor).

    Attributes
    ----------
    estimated : tuple of int
        The regressors whose parameters are estimated, in the estimator's order.
    inv_scales : tuple of float
        One over each estimated parameter's scale (the estimator works on normalised parameters).
    fixed : tuple of (int, float)
        The other regressors, each with its parameter's nominal value.
    drive_limit_v, adapt_from_s, reversal_speed_mm_s : float
        The drive's limit, when the estimator may start, and the reference speed under which it does not learn.
    """

    estimated: tuple[int, ...]
    inv_scales: tuple[float, ...]
    fixed: tuple[tuple[int, float], ...]
    drive_limit_v: float
    adapt_from_s: float
    reversal_speed_mm_s: float


def regressors(ops: Ops, w: Any, r: Any, r1: Any, r2: Any, r3: Any) -> None:
    """The regressors ``[r3, r2, r1, r, 1, sgn(r1)]`` (r1 to r3: the reference's first to third derivatives) into
    ``w`` (six entries, or rows), at the middle of the tick's interval (where the drive is held)."""
    w[0], w[1], w[2], w[3], w[4] = r3, r2, r1, r, 1.0
    w[5] = ops.sign(r1)


def feedforward_tick(ops: Ops, c: Composition, theta: Any, w: Any, feedback_v: Any, rho: Any,
                     t_s: float) -> tuple[Any, Any, Any, Any, Any, Any]:
    """One tick's feedforward and drive from the regressors ``w`` (:func:`regressors`).

    Returns ``(u1, u, saturated, adapting, w_est, fixed_part)``: the feedforward, the saturated drive with the
    feedback ``feedback_v`` added, which way it saturated, whether the estimator learns from this tick, the
    estimated parameters' normalised regressors, and the fixed parameters' part of the feedforward (of the
    reference coil; ``rho`` scales both to this coil). The estimator's target is :func:`estimator_target`.
    """
    w_est = ops.scaled_rows(w, c.estimated, c.inv_scales)
    fixed_part = ops.weighted_rows(w, c.fixed)
    u1 = feedforward_v(ops, theta, w_est, fixed_part, rho)
    u, saturated = saturate(ops, u1 + feedback_v, c.drive_limit_v)
    learn = adapting(saturated, t_s, w[2], c.adapt_from_s, c.reversal_speed_mm_s)
    return u1, u, saturated, learn, w_est, fixed_part


def estimator_target(drive_v: Any, rho: Any, fixed_part: Any) -> Any:
    """What the estimated parameters should explain: the drive sent, referred to the reference coil, less the
    fixed parameters' part (so the estimator's error is the feedback's share: feedback-error learning)."""
    return drive_v / rho - fixed_part


# -- feedforward, drive, adaptation ----------------------------------------------------------------------------

def feedforward_v(ops: Ops, theta: Any, w_est: Any, fixed_part: Any, rho: Any) -> Any:
    """u1: the estimated parameters times their normalised regressors, plus the fixed parameters' part, for this
    coil (``rho``: its resistance over the reference coil's, whose parameters these are)."""
    return (ops.dot(theta, w_est) + fixed_part) * rho


def saturate(ops: Ops, drive_v: Any, limit_v: float) -> tuple[Any, Any]:
    """The drive within +/- the limit, and which way it saturated (+1, -1, 0)."""
    saturated = (drive_v >= limit_v) * 1 - (drive_v <= -limit_v) * 1
    return ops.clip(drive_v, limit_v), saturated


def adapting(saturated: Any, t_s: float, reference_velocity_mm_s: Any, adapt_from_s: float,
             reversal_speed_mm_s: float) -> Any:
    """Whether the estimator learns from this tick: the plant got the drive (no saturation), the excitation is
    running, and the rack slides (not near a reversal, where it sticks and sgn(r') explains nothing)."""
    return (saturated == 0) & (t_s >= adapt_from_s) & (abs(reference_velocity_mm_s) >= reversal_speed_mm_s)


# -- the estimators --------------------------------------------------------------------------------------------

def rls_update(ops: Ops, theta: Any, P: Any, w: Any, y: Any, forgetting: float, max_trace: float,
               ok: Any = True) -> tuple[Any, Any]:
    """Recursive least squares with forgetting, in place: ``theta`` moves to explain ``y`` by ``w``.

    Returns the a-priori error ``y - w . theta`` and where the update applied (``ok``, a finite error and a
    positive gain denominator). ``P`` is bounded to ``trace(P) <= max_trace`` against covariance wind-up.
    """
    err = y - ops.dot(theta, w)
    pw = ops.matvec(P, w)
    denom = forgetting + ops.dot(w, pw)
    ok = ok & ops.isfinite(err) & (denom > 0.0) & ops.isfinite(denom)
    if ops.any(ok):
        gain = ops.divide(pw, denom)
        ops.add_scaled(theta, gain, err, ok)
        ops.rank_one_down(P, gain, pw, 1.0 / forgetting, ok)
        ops.bound_trace(P, max_trace)
    return err, ok


def gradient_update(ops: Ops, theta: Any, gains_per_tick: Any, w: Any, y: Any, ok: Any = True) -> tuple[Any, Any]:
    """The paper's gradient law (eq. 14), normalised: ``theta += T gamma w err / (1 + |w|^2)``, in place."""
    err = y - ops.dot(theta, w)
    ok = ok & ops.isfinite(err)
    if ops.any(ok):
        ops.add_scaled(theta, ops.multiply(gains_per_tick, w), err / (1.0 + ops.dot(w, w)), ok)
    return err, ok


# -- the coil figure the drive is scaled by --------------------------------------------------------------------

class CoilAverage:
    """The coil's resistance estimate averaged over the last ``window`` ticks (the excitation's longest period):
    the estimate itself wobbles with the motion, and that wobble, in the drive, would move a1.

    ``first`` is the value before any tick (a float, or an (N,) array).
    """

    def __init__(self, window: int, first: Any) -> None:
        self.window = window
        self._ring = [first * 0.0] * window if isinstance(first, float) else np.zeros((window, *np.shape(first)))
        self._sum = first * 0.0
        self._added = 0
        self.mean = first

    def add(self, resistance_ohm: Any) -> Any:
        """This tick's estimate in; the average out."""
        slot = self._added % self.window
        self._sum = self._sum + (resistance_ohm - self._ring[slot])
        self._ring[slot] = resistance_ohm
        self._added += 1
        self.mean = self._sum / min(self._added, self.window)
        return self.mean

    def take(self, keep: np.ndarray) -> None:
        """Keep the tests ``keep`` (indices) of an (N,) average: a batch whose other tests have stopped."""
        self._ring = self._ring[:, keep]
        self._sum, self.mean = self._sum[keep], self.mean[keep]


__all__ = ["ARRAYS", "SCALAR", "ArrayOps", "CoilAverage", "Ops", "PidCoefficients", "PidState", "adapting",
           "derivative_filter_coefficients",
           "feedforward_v", "gradient_update", "pid_update", "rls_update", "saturate"]
