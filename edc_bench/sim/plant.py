"""The physical plant behind the rig: rack, spring, coil, amplifier, friction.

Paper eqs. 1-4 with a spring preload and friction with stiction::

    m x'' + c x' + k' x + F_pre + F_f = k_i i          (k' = k - k_x)
    L i' + R i = k_A u
    F_f = F_c sgn(x')  while sliding;  |F_f| <= F_s at rest (stiction)

Units: x in mm, x' in mm/s, i in A, u in V, forces in N, mass in kg (used as
``mass_kg * 1e-3`` N s^2/mm so that the equation holds with x in mm).

Integration is exact for the linear part: between friction events the state
``z = [x, x', i]`` obeys ``z' = A z + B w`` with a constant input
``w = [k_A u, -(F_pre + F_c s)]``, and one step is ``z <- Phi z + Gamma w``
with ``Phi, Gamma`` from the matrix exponential (the stiff coil, its L/R
near a command period, needs no small steps). A whole command period is taken in one step unless the
velocity changes sign or the rack sits stuck; then the period is replayed in
quanta of ``quantum_s`` (0.1 ms) with a Karnopp stick/slip rule, so that
stick-slip at reversals ("chattering", paper Figs. 4c and 5c) is resolved.

Two departures from the linear model, both off in the shipped variants but
the test variant ``p-edc-hard``: a force constant that varies with the
rack's position, k_i(x) = k_i (1 + s (x - x_m)), and Stribeck friction, which
falls from the breakaway force F_s to F_c as the rack speeds up. The matrices
keep the constant k_i; the difference ``k_i s (x - x_m) i`` and the
speed-dependent friction enter the constant-force input, held over each
step (a period, or a quantum near reversals). The pull's difference is taken
at the step's middle (the position a half step on at the starting speed):
taken at its start, it would lag half a step behind the rack, and a lagging
position-dependent force acts as damping, which the identification then
found in a1 and the truth did not hold.
The friction is taken at the starting speed.

The step itself, exact or in quanta, is :func:`edc_bench.sim.kernels.step_valve`, the one definition the
batch path's N valves take too (there compiled by numba where it is installed; here run as Python).

The coil warms with the heat ``R i^2`` it dissipates: every
``THERMAL_STEP_S`` of plant time its temperature is stepped (first order,
:func:`~edc_bench.physics.coil.temperature_after_c`) with the mean power since
the last step, and its resistance, hence the coil's row of ``A``, follows.
The plant knows nothing of buses, files or wall-clock time.
"""

from __future__ import annotations

import math

import numpy as np

from edc_bench.physics.coil import resistance_at_ohm, temperature_after_c
from edc_bench.physics.matrix_exponential import expm
from edc_bench.physics.parameters import PlantParameters
from edc_bench.sim.kernels import pump_constants, step_valve

DEFAULT_QUANTUM_S = 1e-4
# Karnopp dead band: below this speed a rack whose forces are within stiction
# sticks. Without it an overdamped approach would slide forever, ever slower.
STICK_SPEED_MM_S = 1e-3
#: Plant time between steps of the coil's temperature (its thermal time constant is minutes).
THERMAL_STEP_S = 0.1


class _Step:
    """Precomputed exact discretisation for a step of n quanta: Phi and Gamma as the kernel indexes them,
    ``phi[row, valve]``, for one valve (column 0).

    The kernel runs here as Python: a mapping from (row, 0) to a float answers ``phi[row, 0]`` faster than a numpy
    array, whose elements would also make every product a numpy scalar's (the same bits, slower).
    """

    __slots__ = ("dt_s", "gam", "phi")

    def __init__(self, a: np.ndarray, b: np.ndarray, quanta: int, quantum_s: float) -> None:
        self.dt_s = quanta * quantum_s
        aug = np.zeros((5, 5))
        aug[:3, :3] = a
        aug[:3, 3:] = b
        e = expm(aug * self.dt_s)
        self.phi = {(row, 0): float(value) for row, value in enumerate(e[:3, :3].ravel())}
        self.gam = {(row, 0): float(value) for row, value in enumerate(e[:3, 3:].ravel())}


class Plant:
    """State and stepping of the rack actuator.

    Parameters
    ----------
    params : PlantParameters
        The physics.
    quantum_s : float, optional
        Finest time step, used around velocity reversals and while stuck.
    position_mm : float, optional
        Initial rack position (at rest), 0 by default (the safe stop).
    """

    def __init__(self, params: PlantParameters, quantum_s: float = DEFAULT_QUANTUM_S,
                 position_mm: float = 0.0) -> None:
        if params.stiction_friction_n < params.coulomb_friction_n:
            raise ValueError("stiction_friction_n must be >= coulomb_friction_n")
        self.params = params
        self.quantum_s = quantum_s
        self._a, self._b = params.state_matrices()
        self._steps: dict[int, _Step] = {}
        self._quantum = self._step(1)
        self.x_mm = float(position_mm)
        self.v_mm_s = 0.0
        self.i_a = 0.0
        self.stuck = True
        self.drive_v = 0.0
        self.elapsed_quanta = 0
        self.stick_events = 0  # transitions from sliding to stuck, for analysis
        p = params
        self._m = p.mass_n_s2_per_mm
        self._k = p.net_stiffness_n_per_mm
        self._ki = p.force_constant_n_per_a
        self._fpre = p.preload_n
        self._fc = p.coulomb_friction_n
        self._fs = p.stiction_friction_n
        self._slope = p.force_constant_slope_per_mm
        self._x_mid = p.force_constant_mid_mm
        self._pump = tuple(float(value) for value in pump_constants(
            p.linear, p.preload_n, p.stribeck_velocity_mm_s, p.force_constant_n_per_a, p.force_constant_slope_per_mm,
            p.force_constant_mid_mm, p.net_stiffness_n_per_mm, p.stroke_mm, STICK_SPEED_MM_S, p.rack_bind_n,
            p.rack_bind_at_mm, p.rack_bind_width_mm, p.rack_friction_slope_n_per_mm))
        self.coil_temp_c = p.coil_temp_c
        self.resistance_ohm = p.resistance_ohm
        self._r20 = p.resistance_20c_ohm
        self._heat_j = 0.0
        self._thermal_quanta = max(1, round(THERMAL_STEP_S / quantum_s))
        self._next_thermal = self._thermal_quanta

    @property
    def time_s(self) -> float:
        """Simulated time since creation."""
        return self.elapsed_quanta * self.quantum_s

    def _step(self, n: int) -> _Step:
        step = self._steps.get(n)
        if step is None:
            step = _Step(self._a, self._b, n, self.quantum_s)
            self._steps[n] = step
        return step

    def prepare(self, max_quanta: int) -> None:
        """Precompute steps of 1..max_quanta quanta (avoids a first-use delay in real time)."""
        for n in range(1, max_quanta + 1):
            self._step(n)

    def set_drive_v(self, drive_v: float) -> None:
        """Set the amplifier input (held until changed); clipped to the amplifier limit."""
        limit = self.params.amplifier_limit_v
        if drive_v != drive_v:  # NaN: an amplifier has no such input; treat as 0 V
            drive_v = 0.0
        self.drive_v = -limit if drive_v < -limit else (limit if drive_v > limit else drive_v)

    def _pull_n(self, x_mm: float, i_a: float) -> float:
        """The solenoid's pull k_i(x) i."""
        return self._ki * (1.0 + self._slope * (x_mm - self._x_mid)) * i_a

    def net_force_at_rest_n(self) -> float:
        """Force on the rack if it were at rest, before friction."""
        return self._pull_n(self.x_mm, self.i_a) - self._k * self.x_mm - self._fpre

    def advance(self, n_quanta: int) -> None:
        """Advance the plant by ``n_quanta`` quanta with the current drive.

        Parameters
        ----------
        n_quanta : int
            Number of quanta (``quantum_s`` each) to integrate.
        """
        if n_quanta <= 0:
            return
        self.elapsed_quanta += n_quanta
        coil_v = self.params.amplifier_gain * self.drive_v
        step, quantum = self._step(n_quanta), self._quantum
        x, v, i, stuck, sticks = step_valve(step.phi, step.gam, 0, step.dt_s, n_quanta, self.x_mm, self.v_mm_s,
                                            self.i_a, self.stuck, quantum.phi, quantum.gam, 0, coil_v, self._fc,
                                            self._fs, self.quantum_s, self._pump)
        self.x_mm, self.v_mm_s, self.i_a, self.stuck = x, v, i, stuck
        self.stick_events += sticks
        self._heat_j += self.resistance_ohm * self.i_a * self.i_a * n_quanta * self.quantum_s
        if self.elapsed_quanta >= self._next_thermal:
            self._step_temperature()

    def _step_temperature(self) -> None:
        """The coil's temperature after the heat since the last step; its resistance and the matrices follow."""
        p = self.params
        span_quanta = self.elapsed_quanta - (self._next_thermal - self._thermal_quanta)
        span_s = span_quanta * self.quantum_s
        self.coil_temp_c = temperature_after_c(self.coil_temp_c, self._heat_j / span_s, span_s, p.ambient_c,
                                               p.thermal_capacity_j_per_k, p.thermal_resistance_k_per_w)
        self._heat_j = 0.0
        self._next_thermal = (self.elapsed_quanta // self._thermal_quanta + 1) * self._thermal_quanta
        if p.temperature_coefficient_per_k == 0.0:
            return
        self.resistance_ohm = resistance_at_ohm(self._r20, self.coil_temp_c, p.temperature_coefficient_per_k)
        self._a[2, 2] = -self.resistance_ohm / p.inductance_h
        self._steps.clear()
        self._quantum = self._step(1)

    def natural_frequency_rad_s(self) -> float:
        """Undamped natural frequency of the linearised mechanics, sqrt(k'/m)."""
        return math.sqrt(self._k / self._m)

    def damping_ratio(self) -> float:
        """Damping ratio of the linearised mechanics, c / (2 sqrt(k' m))."""
        return self.params.damping_n_s_per_mm / (2.0 * math.sqrt(self._k * self._m))
