"""Feedback-error learning: one controller tick, pure.

Per tick k (period T, time t_k = k T), given the rack positions the rig has
reported since the last tick, each answering the command of a tick j (j =
k-1 when every reply comes within its tick; earlier through a USB adapter):

1. error e = mean over those samples of r(t_j) - x_j (one sample, the usual
   case: e = r(t_j) - x_j); PID output u2. With no new sample the last error
   is used again while the newest sample is young enough; after that the
   PID output is held, not updated. Averaging rather than taking the newest
   matters through a USB adapter: when two commands reach the rig in the
   same USB frame, the first was late, and using only the second would hide
   the late samples from the PID while the rack feels the late drives; the
   PID then sees a lag the rack does not have, and its velocity-proportional
   output shows up in a1 (docs/method.md).
2. regressor W = [r''', r'', r', r, 1, sgn(r')] at t_k + T/2, the middle of
   the interval over which the drive is held (zero-order hold).
3. feedforward u1 = W . a_hat; drive u = sat(u1 + u2).
4. estimator update with target u (so its error is e2 = u - u1), skipped
   while the drive saturates, before the excitation starts, and while |r'|
   is small (stick windows at reversals are not explained by sgn(r')).

Only parameters listed as estimated are adapted; the others stay at their
nominal value and their share of u1 is taken off the target.

The coil: each current sample (:meth:`FelController.add_current`) updates
the coil's resistance R_hat (:mod:`edc_bench.control.coil`). The parameters
are kept *referred to the reference coil* (the variant's nominal R_ref): the
feedforward is ``rho W . a_hat`` with ``rho = R_hat / R_ref``, and the
estimator's target is ``u / rho``. A coil that warms during the test (its
drive rises with its resistance) then leaves the regression alone; without
this the drift leaked into af as a wobble (docs/method.md). The
inductive shares of a3, a2 and a1, which do not scale with R, are put right
after the test (:func:`edc_bench.physics.coil.referred_from_estimate`).
R_hat is averaged over the excitation's longest period before use.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from edc_bench.control import law
from edc_bench.control.coil import CoilEstimator
from edc_bench.control.estimators import Estimator
from edc_bench.control.pid import Pid
from edc_bench.control.reference import Reference

if TYPE_CHECKING:
    from edc_bench.control.design import ControllerDesign

#: One row of :func:`reference_table`: r, r', r'', r''' at mid-tick, and r at the tick's start.
ReferenceRow = tuple[float, float, float, float, float]


def reference_table(reference: Reference, period_s: float, ticks: int) -> list[ReferenceRow]:
    """Per tick k: the reference and its derivatives at t_k + T/2 (the regressor's time), and r(t_k).

    Tabulated up front (vectorised), so a tick only looks its row up.
    """
    k = np.arange(ticks, dtype=float)
    mid = reference.tabulate((k + 0.5) * period_s)
    return list(zip(*mid.tolist(), reference.tabulate(k * period_s)[0].tolist(), strict=True))


def regressor_matrix(reference: Reference, t_s: np.ndarray, period_s: float) -> np.ndarray:
    """The six regressors ``[r''', r'', r', r, 1, sgn r']`` at mid-tick of each time in ``t_s`` (one row each)."""
    r, r1, r2, r3 = reference.tabulate(np.asarray(t_s, dtype=float) + 0.5 * period_s)
    return np.column_stack((r3, r2, r1, r, np.ones_like(r), np.sign(r1)))


def condition_number(phi: np.ndarray) -> float:
    """Condition number of the regression's information matrix, columns scaled to unit norm.

    Scaling makes it measure collinearity of the regressors, not their units.
    """
    norms = np.linalg.norm(phi, axis=0)
    norms[norms == 0] = 1.0
    scaled = phi / norms
    return float(np.linalg.cond(scaled.T @ scaled))


class FelController:
    """PID feedback, friction-compensated feedforward and online estimation.

    Build it with :meth:`edc_bench.control.design.ControllerDesign.controller`.

    Parameters
    ----------
    design : ControllerDesign
        Nominal parameters, parameter split, regressor scales, limits and timing.
    reference : Reference
        The rack reference of this test.
    pid : Pid
        The feedback controller.
    estimator : Estimator
        Fits the estimated parameters, in normalised form.

    Attributes
    ----------
    reference_mm : float
        The reference at the last tick's time t_k: what the command carries,
        and what the next sample is compared with.
    reference_velocity_mm_s, feedforward_v, feedback_v : float
        The last tick's r' (at mid-tick), u1 and u2.
    adapting : bool
        Whether the last tick updated the estimator.
    table : list of tuple
        The reference per tick (:func:`reference_table`) for the design's ticks.
    """

    def __init__(self, design: ControllerDesign, reference: Reference, pid: Pid, estimator: Estimator) -> None:
        self.design, self.reference, self.pid, self.estimator = design, reference, pid, estimator
        # the design's numbers the tick reads, bound once (an attribute of self is faster than two lookups)
        self.estimated, self.fixed, self.nominal, self.scales = design.estimated, design.fixed, design.nominal, \
            design.scales
        self.drive_limit_v, self.period_s, self.adapt_from_s = design.drive_limit_v, design.period_s, \
            design.adapt_from_s
        self.reversal_speed_mm_s = design.reversal_speed_mm_s
        self._w = [0.0] * len(design.nominal)
        self._composition = design.composition()
        self._saturated = 0
        self.table = reference_table(reference, design.period_s, design.ticks)
        self.reference_mm = reference.at(0.0)[0]
        self.reference_velocity_mm_s = 0.0
        self.feedforward_v = 0.0
        self.feedback_v = 0.0
        self.adapting = False
        self._error_sum_mm = 0.0
        self._errors = 0
        self._last_error_mm: float | None = None
        self.coil: CoilEstimator[float] = CoilEstimator(design.amplifier_gain, design.reference_resistance_ohm,
                                                        design.period_s)
        self.reference_resistance_ohm = design.reference_resistance_ohm
        self.coil_resistance_ohm = design.reference_resistance_ohm
        self._drives = [math.nan] * design.ticks  # the drive sent at each tick (NaN: not sent, a gap)
        self._coil_average = law.CoilAverage(design.coil_window_ticks, design.reference_resistance_ohm)

    def resync(self) -> None:
        """Ticks were lost to a host stall: take no derivative across the gap (the estimator skips it anyway)."""
        self.pid.restart_derivative()

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

    def add_sample(self, sample_tick: int, measured_mm: float, current_a: float | None = None) -> None:
        """A sample answering tick ``sample_tick``'s command has come (-1: the sample before the first tick).

        The next :meth:`step` compares it with the reference at that tick, averaged with any other sample
        that came since the last step. The coil current taken with it, if given, goes to :meth:`add_current`.
        """
        if current_a is not None:
            self.add_current(sample_tick, current_a)
        j = sample_tick
        if 0 <= j < len(self.table):
            reference_then = self.table[j][4]
        else:  # before the first tick (the start), or beyond the table
            reference_then = self.reference.at(max(j, 0) * self.period_s)[0]
        self._error_sum_mm += reference_then - measured_mm
        self._errors += 1

    def add_current(self, sample_tick: int, current_a: float) -> None:
        """A coil-current sample answering tick ``sample_tick``'s command (taken before its drive applied).

        It pairs with the drive of the tick before, the drive in effect while it came about; a sample
        whose drive is unknown (the first, or after a gap) is left out.
        """
        j = sample_tick - 1
        if 0 <= j < len(self._drives):
            drive = self._drives[j]
            if drive == drive:
                self.coil.update(drive, current_a)

    def step(self, k: int, measured_mm: float | None = None, sample_tick: int | None = None, *,
             newest_usable: bool = False) -> float:
        """Compute the drive for tick ``k``.

        Parameters
        ----------
        k : int
            Tick index (time k T).
        measured_mm : float, optional
            A rack position that came since the last step (or give samples with :meth:`add_sample`).
        sample_tick : int, optional
            The tick whose command ``measured_mm`` answered; ``k - 1`` by default.
        newest_usable : bool, optional
            With no new sample: whether the newest sample is still young enough for its error to be used again;
            if not (the default), the PID output is held.

        Returns
        -------
        float
            Drive voltage u to send, within +/- the drive limit.
        """
        T = self.period_s
        t = k * T
        if measured_mm is not None:
            self.add_sample(k - 1 if sample_tick is None else sample_tick, measured_mm)
        if self._errors:  # the samples that came since the last step, averaged
            error = self._error_sum_mm if self._errors == 1 else self._error_sum_mm / self._errors
            self._error_sum_mm, self._errors, self._last_error_mm = 0.0, 0, error
            u2 = self.pid.update(error, self._saturated)
        else:  # none: the last error again while its sample is young enough, else the PID holds
            last = self._last_error_mm
            if newest_usable and last is not None:
                u2 = self.pid.update(last, self._saturated, True)
            else:
                u2 = self.pid.update(math.nan, self._saturated, False)

        if k < len(self.table):
            r, r1, r2, r3, r_now = self.table[k]
        else:
            r, r1, r2, r3 = self.reference.at(t + 0.5 * T)
            r_now = self.reference.at(t)[0]
        ops, w = law.SCALAR, self._w
        law.regressors(ops, w, r, r1, r2, r3)
        # the parameters are the reference coil's; this coil needs rho times the drive
        if k < len(self._drives):
            self.coil_resistance_ohm = self._coil_average.add(self.coil.resistance_ohm)
        rho = self.coil_resistance_ohm / self.reference_resistance_ohm
        u1, u, self._saturated, self.adapting, w_est, fixed_part = law.feedforward_tick(
            ops, self._composition, self.estimator.theta, w, u2, rho, t)
        if self.adapting:
            self.estimator.update(w_est, law.estimator_target(u, rho, fixed_part))

        if k < len(self._drives):
            self._drives[k] = u
        # the reference at this tick is what the next sample is compared with
        self.reference_mm = r_now
        self.reference_velocity_mm_s, self.feedforward_v, self.feedback_v = r1, u1, u2
        return u
