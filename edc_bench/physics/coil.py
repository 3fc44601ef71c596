"""The coil: resistance with temperature, self-heating, and features referred to the reference coil.

A copper coil's resistance grows with its temperature,
``R(T) = R20 (1 + alpha (T - 20 degC))``, alpha = 0.00393 /K. Over a test
the coil dissipates ``R i^2`` and warms towards ``ambient + P R_th`` with
the time constant ``R_th C_th`` (a first-order thermal model; the simulated
rig steps it, the bench never needs it).

The feedforward parameters the bench identifies are in volts, and the coil
is in them: ``af = R F_c / K`` and ``a1 = (L k' + R c) / K``. With the
coil's resistance measured in the same test (from drive and current), the
features are *referred to the reference coil* (the variant's nominal
``R_ref`` at 20 degC and its nominal inductance ``L``): the values the same
valve would give with that coil::

    af_ref = af R_ref / R
    a1_ref = (a1 - L k' / K) R_ref / R + L k' / K

They depend on the valve's friction and damping only (docs/method.md
section 14). Pure arithmetic: floats or numpy arrays alike.
"""

from __future__ import annotations

import math
from typing import TypeVar

import numpy as np

#: The temperature the coil spec and the nominal resistance are stated at.
REFERENCE_TEMP_C = 20.0

Number = TypeVar("Number", float, np.ndarray)


def resistance_at_ohm(resistance_20c_ohm: Number, temp_c: Number, alpha_per_k: float) -> Number:
    """The resistance at ``temp_c`` of a coil of ``resistance_20c_ohm`` at 20 degC."""
    return resistance_20c_ohm * (1.0 + alpha_per_k * (temp_c - REFERENCE_TEMP_C))


def resistance_20c_ohm(resistance_ohm: Number, temp_c: Number, alpha_per_k: float) -> Number:
    """A resistance measured at ``temp_c`` referred to 20 degC."""
    return resistance_ohm / (1.0 + alpha_per_k * (temp_c - REFERENCE_TEMP_C))


def temperature_after_c(temp_c: Number, power_w: Number, dt_s: float, ambient_c: float, capacity_j_per_k: float,
                        resistance_k_per_w: float) -> Number:
    """Coil temperature after ``dt_s`` dissipating ``power_w`` (held), first-order towards its steady state."""
    steady = ambient_c + power_w * resistance_k_per_w
    decay = math.exp(-dt_s / (capacity_j_per_k * resistance_k_per_w))
    return steady + (temp_c - steady) * decay


def referred_from_estimate(inductive_v: float, estimate: Number, reference_ohm: float,
                           resistance_ohm: Number) -> Number:
    """A parameter as the reference coil gives it, from the loop's estimate.

    The loop divides its target by ``R / R_ref`` (docs/method.md section 14): the resistive share comes out
    referred, but the inductive share ``inductive_v`` comes out scaled by ``R_ref / R``; this puts it right.
    """
    return estimate + inductive_v * (1.0 - reference_ohm / resistance_ohm)


def volts_at_coil(inductive_v: float, referred: Number, reference_ohm: float, resistance_ohm: Number) -> Number:
    """A referred parameter as identified in volts with the measured coil (the paper's af and a1)."""
    return (referred - inductive_v) * resistance_ohm / reference_ohm + inductive_v
