"""The coil's resistance, measured on line from drive and current. Pure arithmetic.

The coil obeys ``k_A u = R i + L di/dt`` whatever the rack does. Multiplied
by ``i`` and summed over a stretch of the test, the inductive term is
``(L/2)(i_end^2 - i_start^2)``: a boundary term that does not grow with the
stretch, so ::

    R = k_A sum(u i) / sum(i^2)

with exponential forgetting (memory ``memory_s``) tracks the resistance as
the coil warms. Each current sample answers a command and was taken before
that command's drive was applied: it pairs with the drive of the command
before it (the drive that was in effect). The current sensor's noise adds
``sigma^2`` to ``sum(i^2)`` only (about 2e-6 relative at the default
variant's 4 A and 5 mA). Works on floats and on numpy arrays (one element
per valve in the batch path) alike.

The inductance is not measured: at this excitation and sensor noise its
trace in the current is below the noise (docs/method.md section 14); the
variant's nominal inductance is used.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from typing import Generic, TypeVar

import numpy as np

Number = TypeVar("Number", float, np.ndarray)

#: Memory of the resistance estimate: short beside the coil's warming (minutes), long beside the sensor noise.
COIL_MEMORY_S = 0.5
#: The prior (the nominal resistance) weighs as much as this many samples at 1 A.
PRIOR_SAMPLES = 10.0


def averaging_window_s(frequencies_hz: Iterable[float]) -> float:
    """What the loop averages the estimate over before use: the excitation's longest period."""
    return 1.0 / min(frequencies_hz)


def measurement_lag_s(frequencies_hz: Iterable[float]) -> float:
    """How far the averaged estimate lags the coil: its memory plus half the averaging window."""
    return COIL_MEMORY_S + 0.5 * averaging_window_s(frequencies_hz)


class CoilEstimator(Generic[Number]):
    """Recursive estimate of the coil's resistance.

    Parameters
    ----------
    amplifier_gain : float
        k_A: coil voltage per volt of drive.
    nominal_ohm : float or numpy.ndarray
        Prior resistance (the reference coil's), forgotten as data come.
    period_s : float
        Time between samples (one per tick).
    memory_s : float, optional
        Time constant of the forgetting.
    """

    def __init__(self, amplifier_gain: float, nominal_ohm: Number, period_s: float,
                 memory_s: float = COIL_MEMORY_S) -> None:
        self.amplifier_gain = amplifier_gain
        self.forgetting = math.exp(-period_s / memory_s)
        self.sum_ii: Number = nominal_ohm * 0.0 + PRIOR_SAMPLES
        self.sum_ui: Number = self.sum_ii * nominal_ohm / amplifier_gain

    def update(self, drive_v: Number, current_a: Number) -> None:
        """One current sample and the drive that was in effect while it came about."""
        lam = self.forgetting
        self.sum_ui = lam * self.sum_ui + drive_v * current_a
        self.sum_ii = lam * self.sum_ii + current_a * current_a

    def take(self, keep: np.ndarray) -> None:
        """Keep the tests ``keep`` (indices) of an (N,) estimate: a batch whose other tests have stopped."""
        self.sum_ui, self.sum_ii = self.sum_ui[keep], self.sum_ii[keep]

    @property
    def resistance_ohm(self) -> Number:
        """The present estimate (the prior until samples have come)."""
        return self.amplifier_gain * self.sum_ui / self.sum_ii
