"""Physical parameters of one rack actuator with one valve fitted (paper eqs. 1-4).

Pure data and the linear algebra that follows from it: the state-space
matrices of the rack, spring and coil, and static equilibria. The simulator
steps these equations (:mod:`edc_bench.sim.plant`); the controller's nominal
model and the gain check read the same parameters.

Units: x in mm, x' in mm/s, i in A, u in V, forces in N, mass in kg (used as
``mass_kg * 1e-3`` N s^2/mm so that the equation holds with x in mm).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from edc_bench.physics.coil import resistance_20c_ohm


@dataclass(frozen=True)
class PlantParameters:
    """Physical parameters of one rack actuator with one valve fitted.

    Attributes
    ----------
    mass_kg : float
        Moving mass m.
    spring_n_per_mm, magnetic_stiffness_n_per_mm : float
        Spring stiffness k and the magnet's negative stiffness k_x.
    preload_n : float
        Spring preload F_pre pushing the rack towards 0 mm (no delivery).
    damping_n_s_per_mm : float
        Total viscous damping c (pump and valve).
    coulomb_friction_n, stiction_friction_n : float
        Sliding friction F_c and breakaway friction F_s (F_s >= F_c).
    resistance_ohm, inductance_h : float
        Coil R and L.
    force_constant_n_per_a : float
        k_i.
    amplifier_gain, amplifier_limit_v : float
        k_A and the amplifier's output limit on u.
    stroke_mm : float
        Hard stops at 0 and ``stroke_mm``.
    coil_temp_c : float
        Coil temperature at the start (``resistance_ohm`` is at this temperature).
    ambient_c : float
        Temperature the coil cools towards.
    temperature_coefficient_per_k, thermal_capacity_j_per_k, thermal_resistance_k_per_w : float
        The coil's resistance per kelvin (relative) and its first-order thermal model
        (:mod:`edc_bench.physics.coil`).
    force_constant_slope_per_mm : float
        Relative change of the force constant per mm of rack travel: k_i(x) = k_i (1 + s (x - x_m)).
        A real proportional solenoid's pull varies with the armature's position; 0 for the linear model.
    force_constant_mid_mm : float
        x_m, where the force constant is ``force_constant_n_per_a`` (the variant's mid-stroke).
    stribeck_velocity_mm_s : float
        Stribeck speed v_s: sliding friction falls from the breakaway force F_s to F_c as
        F_c + (F_s - F_c) exp(-(v / v_s)^2). 0: it falls to F_c as soon as the rack slides.
    rack_bind_n, rack_bind_at_mm, rack_bind_width_mm : float
        A control rack that rubs at one place (bent, or a burr in its guide): friction there is higher by
        ``rack_bind_n`` exp(-((x - at) / width)^2), sliding and at rest alike. 0 N: a straight rack.
    rack_friction_slope_n_per_mm : float
        A rack guide whose friction rises along the stroke: ``slope x`` more (N, x in mm from the stop), sliding
        and at rest alike. 0: friction the same along the stroke.
    """

    mass_kg: float
    spring_n_per_mm: float
    magnetic_stiffness_n_per_mm: float
    preload_n: float
    damping_n_s_per_mm: float
    coulomb_friction_n: float
    stiction_friction_n: float
    resistance_ohm: float
    inductance_h: float
    force_constant_n_per_a: float
    amplifier_gain: float
    amplifier_limit_v: float
    stroke_mm: float
    coil_temp_c: float = 20.0
    ambient_c: float = 20.0
    temperature_coefficient_per_k: float = 0.0
    thermal_capacity_j_per_k: float = 40.0
    thermal_resistance_k_per_w: float = 3.0
    force_constant_slope_per_mm: float = 0.0
    force_constant_mid_mm: float = 0.0
    stribeck_velocity_mm_s: float = 0.0
    rack_bind_n: float = 0.0
    rack_bind_at_mm: float = 0.0
    rack_bind_width_mm: float = 1.0
    rack_friction_slope_n_per_mm: float = 0.0

    @property
    def linear(self) -> bool:
        """True when the plant is the linear model (constant force constant, no Stribeck decay, friction the
        same along the stroke)."""
        return (self.force_constant_slope_per_mm == 0.0 and self.stribeck_velocity_mm_s == 0.0
                and not self.rack_friction_varies)

    @property
    def rack_friction_varies(self) -> bool:
        """True when the rack's friction depends on where it is (a local bind, a slope)."""
        return self.rack_bind_n != 0.0 or self.rack_friction_slope_n_per_mm != 0.0

    def rack_friction_n(self, position_mm: float) -> float:
        """The rack's own friction beyond the valve's at ``position_mm`` (N): a local bind and a slope."""
        bind = 0.0
        if self.rack_bind_n != 0.0:
            bind = self.rack_bind_n * math.exp(-(((position_mm - self.rack_bind_at_mm) / self.rack_bind_width_mm) ** 2))
        return bind + self.rack_friction_slope_n_per_mm * position_mm

    def force_constant_at(self, position_mm: float) -> float:
        """The solenoid's force constant k_i(x) in N/A with the rack at ``position_mm``."""
        return self.force_constant_n_per_a * (1.0 + self.force_constant_slope_per_mm
                                              * (position_mm - self.force_constant_mid_mm))

    def sliding_friction_n(self, speed_mm_s: float) -> float:
        """Friction opposing a rack sliding at ``speed_mm_s`` (Stribeck: F_s at breakaway, F_c when fast)."""
        if self.stribeck_velocity_mm_s <= 0.0:
            return self.coulomb_friction_n
        excess = self.stiction_friction_n - self.coulomb_friction_n
        return self.coulomb_friction_n + excess * math.exp(-(speed_mm_s / self.stribeck_velocity_mm_s) ** 2)

    @property
    def magnetic_stiffness_from_slope_n_per_mm(self) -> float:
        """K_m = s (k' x_m + F_pre): the stiffness the varying force constant adds at mid-stroke's holding current.

        With k_i(x) = k_i (1 + s (x - x_m)) the pull k_i(x) i about x_m at the current i_0 that holds the rack
        there (k_i i_0 = k' x_m + F_pre) grows by k_i s i_0 per mm: a negative stiffness, as k_x is.
        """
        return self.force_constant_slope_per_mm * (self.net_stiffness_n_per_mm * self.force_constant_mid_mm
                                                   + self.preload_n)

    @property
    def resistance_20c_ohm(self) -> float:
        """The coil's resistance referred to 20 degC."""
        return resistance_20c_ohm(self.resistance_ohm, self.coil_temp_c, self.temperature_coefficient_per_k)

    @property
    def net_stiffness_n_per_mm(self) -> float:
        """k' = k - k_x."""
        return self.spring_n_per_mm - self.magnetic_stiffness_n_per_mm

    @property
    def mass_n_s2_per_mm(self) -> float:
        """Mass in the units of the equation of motion (x in mm)."""
        return self.mass_kg * 1e-3

    def state_matrices(self) -> tuple[np.ndarray, np.ndarray]:
        """Continuous-time ``A`` (3x3) and ``B`` (3x2) for ``z = [x, x', i]``.

        Inputs are ``w = [coil voltage k_A u in V, constant force in N]``.
        """
        m = self.mass_n_s2_per_mm
        a = np.array(
            [
                [0.0, 1.0, 0.0],
                [-self.net_stiffness_n_per_mm / m, -self.damping_n_s_per_mm / m, self.force_constant_n_per_a / m],
                [0.0, 0.0, -self.resistance_ohm / self.inductance_h],
            ]
        )
        b = np.array([[0.0, 0.0], [0.0, 1.0 / m], [1.0 / self.inductance_h, 0.0]])
        return a, b

    def equilibrium_mm(self, drive_v: float) -> float:
        """Frictionless rest position for a constant drive (ignoring the stops)."""
        current_a = self.amplifier_gain * drive_v / self.resistance_ohm
        return (self.force_constant_n_per_a * current_a - self.preload_n) / self.net_stiffness_n_per_mm

    def drive_for_position_v(self, position_mm: float) -> float:
        """Constant drive that holds the rack at ``position_mm`` without friction."""
        force_n = self.net_stiffness_n_per_mm * position_mm + self.preload_n
        return force_n / self.force_constant_n_per_a * self.resistance_ohm / self.amplifier_gain
