"""The feedforward parameters that follow from a plant's physics.

Inverting the plant along the reference r (ideal tracking, x = r) gives the
drive the feedforward must supply::

    u1 = a3 r''' + a2 r'' + a1 r' + a0 r + b + af sgn(r')

with K = k_A k_i and k' = k - k_x::

    a3 = L m / K     a2 = (m R + L c) / K     a1 = (L k' + R c) / K
    a0 = R k' / K    b  = R F_pre / K         af = R F_c / K

(see docs/method.md for the derivation).

A solenoid whose force constant varies with position, k_i(x) = k_i (1 + s (x - x_m)),
is linearised about mid-stroke x_m at the current that holds the rack there:
its pull then has the extra negative stiffness K_m = s (k' x_m + F_pre), so
k' becomes k' - K_m and the preload F_pre + K_m x_m (docs/method.md, "A force
constant that varies with position"). For s = 0 nothing changes.
"""

from __future__ import annotations

from typing import NamedTuple

from edc_bench.config.models import Variant
from edc_bench.physics.parameters import PlantParameters
from edc_bench.physics.valve import nominal_plant


class FeedforwardParameters(NamedTuple):
    """The feedforward u1 = a3 r''' + a2 r'' + a1 r' + a0 r + b + af sgn(r').

    Units: a3 V s^3/mm, a2 V s^2/mm, a1 V s/mm, a0 V/mm, b V, af V.
    """

    a3: float
    a2: float
    a1: float
    a0: float
    b: float
    af: float


def feedforward_truth(params: PlantParameters) -> FeedforwardParameters:
    """True feedforward parameters from the physics.

    Parameters
    ----------
    params : PlantParameters
        The plant.

    Returns
    -------
    FeedforwardParameters
        With K = k_A k_i and k' = k - k_x: a3 = L m/K, a2 = (m R + L c)/K,
        a1 = (L k' + R c)/K, a0 = R k'/K, b = R F_pre/K, af = R F_c/K; for a
        force constant that varies with position, linearised about mid-stroke
        (k_i at x_m, k' - K_m for k', F_pre + K_m x_m for F_pre).
    """
    gain = params.amplifier_gain * params.force_constant_n_per_a
    m = params.mass_n_s2_per_mm
    r, l_h, c = params.resistance_ohm, params.inductance_h, params.damping_n_s_per_mm
    k_slope = params.magnetic_stiffness_from_slope_n_per_mm  # 0 for a constant force constant
    k_net = params.net_stiffness_n_per_mm - k_slope
    preload = params.preload_n + k_slope * params.force_constant_mid_mm
    return FeedforwardParameters(
        a3=l_h * m / gain,
        a2=(m * r + l_h * c) / gain,
        a1=(l_h * k_net + r * c) / gain,
        a0=r * k_net / gain,
        b=r * preload / gain,
        af=r * params.coulomb_friction_n / gain,
    )


def nominal_parameters(variant: Variant) -> FeedforwardParameters:
    """Feedforward parameters of the variant's nominal plant, from the data-sheet physics."""
    return feedforward_truth(nominal_plant(variant))


def inductive_shares(variant: Variant) -> FeedforwardParameters:
    """The share of each feedforward parameter that comes from the coil's inductance, not its resistance.

    ``a3 = L m / K``, ``a2`` has ``L c / K`` (c: the nominal new valve's damping), ``a1`` has ``L k' / K``;
    ``a0``, ``b`` and ``af`` have none. With the variant's nominal inductance.
    """
    p = nominal_plant(variant)
    gain = p.amplifier_gain * p.force_constant_n_per_a
    l_h = p.inductance_h
    return FeedforwardParameters(a3=l_h * p.mass_n_s2_per_mm / gain, a2=l_h * p.damping_n_s_per_mm / gain,
                                 a1=l_h * p.net_stiffness_n_per_mm / gain, a0=0.0, b=0.0, af=0.0)
