"""Physical parameters of one rack actuator with one valve fitted (paper eqs. 1-4).

Pure data and the linear algebra that follows from it: the state-space
matrices of the rack, spring and coil, and static equilibria. The simulator
steps these equations (:mod:`edc_bench.sim.plant`); the controller's nominal
model and the gain check read the same parameters.

Units: x in mm, x' in mm/s, i in A, u in V, forces in N, mass in kg (used as
``mass_kg * 1e-3`` N s^2/mm so that the equation holds with x in mm).
"""

from __future__ import annotations

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
