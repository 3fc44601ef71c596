"""A second simulated plant and rack-travel sensor, written from physics alone, to measure the part diagnosis on.

The project's own plant (``edc_bench/sim``) is the one the part diagnosis was tuned on. This module is written
without reading it: only the rig's interface to a plant (:class:`edc_bench.sim.rig.SimulatedRig`) and the variant's
figures (``configs/p-edc-default.toml``) are shared.

Physics
-------
Mechanics (x in mm, v in mm/s, forces in N, the coil current i in A)::

    m x'' = k_i i - k' x - F_pre - F_valve - F_rack,      k' = spring - magnetic stiffness
    L i' + R i = k_A u

with hard, inelastic stops at 0 and the stroke (the preload holds the rack on the 0 stop at rest).

* The valve's friction is a LuGre bristle model: a bristle deflection z with
  ``z' = v - sigma0 |v| z / g(v)``, ``g(v) = F_c + (F_s - F_c) exp(-(v/v_s)^2)`` (a Stribeck hump of
  ``stiction_ratio`` over the Coulomb level), ``F_valve = sigma0 z + sigma1 exp(-(v/v_s)^2) z' + c_valve v``.
* The rack's own friction (plungers, guides) is a smooth Coulomb law ``F_r(x) tanh(v / v0) + c_rack v``, whose
  level ``F_r(x)`` carries the rack's faults: a uniform drag, raised-cosine binds (a local bump of friction, a few
  mm wide), a quadratic rise along the stroke, a bent rack (one strong, wide bind).

The state (x, v, i, z) is integrated by classical RK4 in substeps of 10 us (ten per 0.1 ms quantum), the drive held.

The sensor: an inductive half-bridge rack-travel sensor read by an analogue conditioner: ``reading = zero +
gain x + kink(x) + noise``, quantised, where the non-linearity is a local S-kink (the derivative of a Gaussian)
centred at 13.5 mm, the noise is first-order coloured, a bad contact drops the conditioner's output to its rail
(0 mm) for 2-6 ms, and EMI adds single-sample spikes of 0.3-1 mm of either sign.

Run ``python -m tests.parts.second_plant`` for the table of every case.
"""

from __future__ import annotations

import dataclasses
import math
import os
import sys
import tempfile
import time
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from edc_bench.bench import BenchOptions, BenchResult, run_on_simulated_rig
from edc_bench.cli.calibrate_cmd import kept_figures
from edc_bench.config import Variant, load_variant
from edc_bench.config.loader import variant_file
from edc_bench.physics.valve import ValveSpec
from edc_bench.records.advice import Action
from edc_bench.sim.rig import SimulatedRig
from edc_bench.verdict.baseline import Baseline, BaselineTest, baseline_from_tests, station_baseline_path, \
    write_baseline
from edc_bench.verdict.baseline_source import BaselineSource
from edc_bench.verdict.part_sections import Part
from edc_bench.verdict.verdicts import Verdict

try:
    from numba import njit
except ImportError:  # pragma: no cover - numba is optional: the same kernel runs as Python, slower
    def njit(*args: Any, **kwargs: Any) -> Any:
        """Stand-in for numba's decorator: the function itself."""
        if args and callable(args[0]):
            return args[0]
        return lambda function: function

#: The plant's time quantum (the rig advances it in whole quanta).
QUANTUM_S = 1e-4
#: RK4 substeps per quantum.
SUBSTEPS = 10
#: The variant this module brings up from p-edc-default.
VARIANT_NAME = "p-edc-second"
#: The new valve's own friction and damping (config [valve]); a worn valve's (0.25 mm clearance).
NEW_FRICTION_N, NEW_DAMPING_N_S_PER_MM = 0.5, 0.015
WORN_FRICTION_N, WORN_DAMPING_N_S_PER_MM = 0.76, 0.039
#: Valve-to-valve spread (relative standard deviation) of friction and damping.
VALVE_SPREAD_REL = 0.03

# LuGre valve contact
_SIGMA0_N_PER_MM = 300.0  # bristle stiffness: 1.7 um of presliding at 0.5 N
_SIGMA1_N_S_PER_MM = 0.3  # bristle damping (about half the critical with the rack's mass)
_STRIBECK_MM_S = 0.5
# the rack's smooth Coulomb law
_RACK_V0_MM_S = 0.3

# parameter vector of the kernel
(_M, _KX, _FPRE, _KI, _KA, _R, _L, _FC, _FS, _VS, _SIG0, _SIG1, _CV, _CR, _V0, _DRAG,
 _B1, _B1X, _B1W, _B2, _B2X, _B2W, _SL, _SL0, _SL1, _STROKE, _NPARAM) = range(27)


@njit(cache=False)
def _rack_level(x: float, p: np.ndarray) -> float:
    """The rack's Coulomb friction level at ``x``: uniform drag, two raised-cosine binds, a quadratic rise."""
    level = p[_DRAG]
    for peak, at, width in ((p[_B1], p[_B1X], p[_B1W]), (p[_B2], p[_B2X], p[_B2W])):
        d = (x - at) / width
        if peak != 0.0 and abs(d) < 0.5:
            level += peak * 0.5 * (1.0 + math.cos(2.0 * math.pi * d))
    if p[_SL] != 0.0 and x > p[_SL0]:
        s = (x - p[_SL0]) / (p[_SL1] - p[_SL0])
        level += p[_SL] * s * s
    return level


@njit(cache=False)
def _derivatives(x: float, v: float, i: float, z: float, u: float, p: np.ndarray) -> tuple[float, float, float, float]:
    """d/dt of (x, v, i, z)."""
    r = v / p[_VS]
    hump = math.exp(-r * r)
    g = p[_FC] + (p[_FS] - p[_FC]) * hump
    zdot = v - p[_SIG0] * abs(v) * z / g
    f_valve = p[_SIG0] * z + p[_SIG1] * hump * zdot + p[_CV] * v
    f_rack = _rack_level(x, p) * math.tanh(v / p[_V0]) + p[_CR] * v
    f_net = p[_KI] * i - p[_KX] * x - p[_FPRE] - f_valve - f_rack
    return v, 1e3 * f_net / p[_M], (p[_KA] * u - p[_R] * i) / p[_L], zdot


@njit(cache=False)
def _rk4(x: float, v: float, i: float, z: float, u: float, p: np.ndarray,
         dt: float) -> tuple[float, float, float, float]:
    """One classical RK4 step of (x, v, i, z), then the inelastic stops."""
    h = 0.5 * dt
    k1 = _derivatives(x, v, i, z, u, p)
    k2 = _derivatives(x + h * k1[0], v + h * k1[1], i + h * k1[2], z + h * k1[3], u, p)
    k3 = _derivatives(x + h * k2[0], v + h * k2[1], i + h * k2[2], z + h * k2[3], u, p)
    k4 = _derivatives(x + dt * k3[0], v + dt * k3[1], i + dt * k3[2], z + dt * k3[3], u, p)
    x += dt / 6.0 * (k1[0] + 2.0 * k2[0] + 2.0 * k3[0] + k4[0])
    v += dt / 6.0 * (k1[1] + 2.0 * k2[1] + 2.0 * k3[1] + k4[1])
    i += dt / 6.0 * (k1[2] + 2.0 * k2[2] + 2.0 * k3[2] + k4[2])
    z += dt / 6.0 * (k1[3] + 2.0 * k2[3] + 2.0 * k3[3] + k4[3])
    if x <= 0.0:
        x = 0.0
        v = max(v, 0.0)
    elif x >= p[_STROKE]:
        x = p[_STROKE]
        v = min(v, 0.0)
    return x, v, i, z


@njit(cache=False)
def _advance(s: np.ndarray, p: np.ndarray, u: float, steps: int, dt: float) -> None:
    """Integrate the state ``s`` = (x, v, i, z) over ``steps`` substeps of ``dt`` with the drive ``u`` held.

    A substep is split further while the bristles' rate (sigma0 |v| / F_c) makes RK4 stiff: at the speeds of a
    normal test never, in a slam against a stop (a drive at its limit) for a few ms."""
    x, v, i, z = s[0], s[1], s[2], s[3]
    for _ in range(steps):
        rate = p[_SIG0] * abs(v) / p[_FC] + 1e3 * (p[_SIG1] + p[_CV] + p[_CR]) / p[_M]
        split = max(1, int(math.ceil(rate * dt / 0.4)))
        for _ in range(split):
            x, v, i, z = _rk4(x, v, i, z, u, p, dt / split)
    s[0], s[1], s[2], s[3] = x, v, i, z


@dataclass(frozen=True)
class ValveFit:
    """The valve fitted: its own Coulomb friction and damping (the pump's damping is added by the plant).

    Attributes
    ----------
    friction_n : float
        Coulomb level of the valve's LuGre contact, N.
    damping_n_s_per_mm : float
        The valve's viscous damping, N s/mm.
    label : str
        What it is, for the table.
    """

    friction_n: float = NEW_FRICTION_N
    damping_n_s_per_mm: float = NEW_DAMPING_N_S_PER_MM
    label: str = "new"


@dataclass(frozen=True)
class RackShape:
    """The pump's control rack: extra friction along its stroke (all zero: a sound rack).

    Attributes
    ----------
    drag_n, drag_n_s_per_mm : float
        Uniform drag: extra Coulomb friction and viscous damping.
    binds : tuple of (float, float, float)
        Up to two binds: (peak extra friction N, centre mm, full width mm), raised-cosine shaped.
    slope_n : float
        Friction rising quadratically along the stroke: zero at ``slope_from_mm``, ``slope_n`` at ``slope_to_mm``.
    slope_from_mm, slope_to_mm : float
        Where the rise starts and where it reaches ``slope_n``.
    """

    drag_n: float = 0.0
    drag_n_s_per_mm: float = 0.0
    binds: tuple[tuple[float, float, float], ...] = ()
    slope_n: float = 0.0
    slope_from_mm: float = 4.0
    slope_to_mm: float = 16.0


@dataclass(frozen=True)
class SensorShape:
    """The rack-travel sensor's misreading (the defaults: a sound sensor).

    Attributes
    ----------
    gain : float
        Reading per mm of travel, about the 0 mm end.
    zero_mm : float
        Zero offset beyond the sensor's stated one.
    kink_mm : float
        The S-kink's size: its largest deviation from the best straight line over the swing, mm.
    kink_at_mm, kink_width_mm : float
        Where the kink is centred and its width (the Gaussian's standard deviation).
    noise_scale : float
        Noise as a multiple of the stated noise.
    dropouts_per_s : float
        Bad-contact dropouts (the reading at the 0 mm rail for 2-6 ms), Poisson rate.
    spikes_per_s : float
        EMI spikes (single samples 0.3-1 mm off, either sign), Poisson rate.
    """

    gain: float = 1.0
    zero_mm: float = 0.0
    kink_mm: float = 0.0
    kink_at_mm: float = 13.5
    kink_width_mm: float = 2.0
    noise_scale: float = 1.0
    dropouts_per_s: float = 0.0
    spikes_per_s: float = 0.0


class SecondPlant:
    """The rack actuator with a LuGre valve and a position-dependent rack friction, for :class:`SimulatedRig`.

    Parameters
    ----------
    variant : Variant
        Its rack, coil and valve sections give the figures.
    valve : ValveFit
        The valve fitted.
    rack : RackShape, optional
        The rack's faults (sound by default).
    quantum_s : float, optional
        The time quantum the rig advances it by.
    """

    def __init__(self, variant: Variant, valve: ValveFit, rack: RackShape | None = None,
                 quantum_s: float = QUANTUM_S) -> None:
        rack = rack or RackShape()
        if len(rack.binds) > 2:
            raise ValueError("at most two binds")
        binds = list(rack.binds) + [(0.0, 0.0, 1.0)] * (2 - len(rack.binds))
        r, c, vv = variant.rack, variant.coil, variant.valve
        p = np.zeros(_NPARAM)
        p[_M], p[_KX], p[_FPRE] = r.mass_kg, r.spring_n_per_mm - c.magnetic_stiffness_n_per_mm, r.preload_n
        p[_KI], p[_KA], p[_R], p[_L] = c.force_constant_n_per_a, c.amplifier_gain, c.resistance_ohm, \
            c.inductance_mh * 1e-3
        p[_FC], p[_FS], p[_VS] = valve.friction_n, valve.friction_n * vv.stiction_ratio, _STRIBECK_MM_S
        p[_SIG0], p[_SIG1], p[_CV] = _SIGMA0_N_PER_MM, _SIGMA1_N_S_PER_MM, valve.damping_n_s_per_mm
        p[_CR], p[_V0], p[_DRAG] = r.damping_n_s_per_mm + rack.drag_n_s_per_mm, _RACK_V0_MM_S, rack.drag_n
        (p[_B1], p[_B1X], p[_B1W]), (p[_B2], p[_B2X], p[_B2W]) = binds
        p[_SL], p[_SL0], p[_SL1], p[_STROKE] = rack.slope_n, rack.slope_from_mm, rack.slope_to_mm, r.stroke_mm
        self.params = p
        self.limit_v = c.amplifier_limit_v
        self.resistance_ohm = c.resistance_ohm
        self.coil_temp_c = 20.0
        self.quantum_s = quantum_s
        self.elapsed_quanta = 0
        self.drive_v = 0.0
        self._state = np.zeros(4)  # x, v, i, z: at rest on the 0 stop, no current
        self._steps_per_quantum = SUBSTEPS
        self._dt = quantum_s / SUBSTEPS

    @property
    def x_mm(self) -> float:
        """Rack position, mm."""
        return float(self._state[0])

    @property
    def v_mm_s(self) -> float:
        """Rack speed, mm/s."""
        return float(self._state[1])

    @property
    def i_a(self) -> float:
        """Coil current, A."""
        return float(self._state[2])

    @property
    def time_s(self) -> float:
        """Simulated time reached."""
        return self.elapsed_quanta * self.quantum_s

    def set_drive_v(self, volts: float) -> None:
        """Set the amplifier's input (clipped to its limit; NaN drives 0 V)."""
        self.drive_v = 0.0 if math.isnan(volts) else max(-self.limit_v, min(self.limit_v, float(volts)))

    def prepare(self, max_quanta: int) -> None:
        """Nothing to prepare (the kernel needs no buffers)."""

    def advance(self, n_quanta: int) -> None:
        """Integrate ``n_quanta`` quanta with the drive held."""
        if n_quanta <= 0:
            return
        _advance(self._state, self.params, self.drive_v, n_quanta * self._steps_per_quantum, self._dt)
        self.elapsed_quanta += n_quanta


def kink_shape(x_mm: float, shape: SensorShape) -> float:
    """The sensor's S-kink at ``x_mm`` per unit amplitude: the derivative of a Gaussian (odd about its centre)."""
    d = (x_mm - shape.kink_at_mm) / shape.kink_width_mm
    return d * math.exp(-0.5 * d * d)


def kink_amplitude(shape: SensorShape) -> float:
    """The amplitude that makes the kink's largest deviation from the best straight line over the test's motion
    (10 mm + 4 mm at 0.5 Hz + 0.5 mm at 3 Hz, time-weighted) equal ``shape.kink_mm``."""
    if shape.kink_mm == 0.0:
        return 0.0
    t = np.linspace(0.0, 2.0, 20001)
    r = 10.0 + 4.0 * np.sin(np.pi * t) + 0.5 * np.sin(6.0 * np.pi * t)
    e = np.array([kink_shape(float(x), shape) for x in r])
    residual = e - np.polyval(np.polyfit(r, e, 1), r)
    return shape.kink_mm / float(np.abs(residual).max())


class SecondSensor:
    """The rack-travel sensor's reading of the plant, installed in place of the rig's.

    Parameters
    ----------
    rig : SimulatedRig
        The rig whose hardware it reads through (its ``lvdt_disconnected`` switch still gives NaN).
    plant : SecondPlant
        What it measures.
    variant : Variant
        Its [sensors.lvdt] section: stated noise, resolution and zero offset.
    shape : SensorShape
        The misreading.
    rng : numpy.random.Generator
        Noise and events.
    """

    #: first-order colouring of the noise (sample to sample)
    NOISE_POLE = 0.5
    #: the conditioner's output rail in a bad-contact dropout
    RAIL_MM = 0.0

    def __init__(self, rig: SimulatedRig, plant: SecondPlant, variant: Variant, shape: SensorShape,
                 rng: np.random.Generator) -> None:
        lvdt = variant.sensors.lvdt
        self.rig, self.plant, self.shape, self.rng = rig, plant, shape, rng
        self.noise_sd = lvdt.noise_sd * shape.noise_scale
        self.resolution = lvdt.resolution
        self.zero_mm = lvdt.offset + shape.zero_mm
        self.kink_amplitude = kink_amplitude(shape)
        self._noise = 0.0
        self._last_s: float | None = None
        self._dropout_until_s = -math.inf
        self.dropouts = 0
        self.spikes = 0

    def _event(self, rate_per_s: float, dt_s: float) -> bool:
        return rate_per_s > 0.0 and self.rng.random() < -math.expm1(-rate_per_s * dt_s)

    def sample(self) -> float:
        """One reading, mm (NaN with the sensor disconnected)."""
        if self.rig.hardware.lvdt_disconnected:
            return math.nan
        t = self.plant.time_s
        dt = 0.0 if self._last_s is None else max(0.0, t - self._last_s)
        self._last_s = t
        s, x = self.shape, self.plant.x_mm
        a = self.NOISE_POLE
        self._noise = a * self._noise + math.sqrt(1.0 - a * a) * self.noise_sd * self.rng.standard_normal()
        if t < self._dropout_until_s:
            return self.RAIL_MM
        if self._event(s.dropouts_per_s, dt):
            self.dropouts += 1
            self._dropout_until_s = t + self.rng.uniform(2e-3, 6e-3)
            return self.RAIL_MM
        reading = self.zero_mm + s.gain * x + self.kink_amplitude * kink_shape(x, s) + self._noise
        if self._event(s.spikes_per_s, dt):
            self.spikes += 1
            reading += self.rng.choice((-1.0, 1.0)) * self.rng.uniform(0.3, 1.0)
        return round(reading / self.resolution) * self.resolution


def build_rig(variant: Variant, valve: ValveFit, rack: RackShape | None = None, sensor: SensorShape | None = None,
              seed: int = 0) -> SimulatedRig:
    """A :class:`SimulatedRig` (its firmware, current sensor and supply) over :class:`SecondPlant` and
    :class:`SecondSensor`.

    Parameters
    ----------
    variant : Variant
    valve : ValveFit
    rack : RackShape, optional
    sensor : SensorShape, optional
    seed : int, optional
        Seeds the rig's current sensor and this sensor's noise and events.

    Returns
    -------
    SimulatedRig
        With ``plant`` and ``hardware.plant`` replaced and ``hardware.sample_position_mm`` reading this sensor
        (kept as ``rig.second_sensor``).
    """
    rig = SimulatedRig(variant, ValveSpec(clearance_mm=variant.valve.clearance_new_mm), seed)
    plant = SecondPlant(variant, valve, rack, quantum_s=rig.options.quantum_s)
    rig.plant = plant  # type: ignore[assignment]
    rig.hardware.plant = plant  # type: ignore[assignment]
    reading = SecondSensor(rig, plant, variant, sensor or SensorShape(), np.random.default_rng([seed, 2]))
    rig.hardware.sample_position_mm = reading.sample  # type: ignore[method-assign]
    rig.second_sensor = reading  # type: ignore[attr-defined]
    return rig


def spread_valve(base: ValveFit, seed: int) -> ValveFit:
    """``base`` with this valve's own spread of friction and damping (a few per cent, seeded)."""
    rng = np.random.default_rng([seed, 1])
    f, c = 1.0 + VALVE_SPREAD_REL * rng.standard_normal(2)
    return dataclasses.replace(base, friction_n=base.friction_n * f, damping_n_s_per_mm=base.damping_n_s_per_mm * c)


def run_test(variant: Variant, valve: ValveFit, rack: RackShape | None = None, sensor: SensorShape | None = None,
             seed: int = 0, classify: bool = True) -> BenchResult:
    """One bench test on :func:`build_rig`'s rig, in simulated time.

    Parameters
    ----------
    variant : Variant
    valve : ValveFit
        The valve (its spread already applied).
    rack : RackShape, optional
    sensor : SensorShape, optional
    seed : int, optional
    classify : bool, optional
        Judge the valve (off for the baseline's tests).

    Returns
    -------
    BenchResult
    """
    rig = build_rig(variant, valve, rack, sensor, seed)
    return run_on_simulated_rig(variant, rig, BenchOptions(valve_id=f"{valve.label} (seed {seed})",
                                                            classify=classify), seed=seed)


# --- bringing the pump type up ---------------------------------------------------------------------------------


def write_variant(folder: Path) -> Path:
    """``p-edc-second.toml`` in ``folder``: p-edc-default under its own name and part number."""
    text = variant_file("p-edc-default").read_text(encoding="utf-8")
    text = text.replace('name = "p-edc-default"', f'name = "{VARIANT_NAME}"', 1)
    text = text.replace('part_number = "PE-EDC-0001"', 'part_number = "PE-EDC-SECOND-SIM"', 1)
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"{VARIANT_NAME}.toml"
    path.write_text(text, encoding="utf-8")
    return path


def calibrate(variant: Variant, tests: int = 5, seed: int = 9000) -> tuple[Baseline, Path]:
    """Run ``tests`` new valves (classify off) and write the station's baseline of ``variant`` from them.

    Parameters
    ----------
    variant : Variant
        The station's variant (:data:`VARIANT_NAME`), with ``EDC_BENCH_VARIANTS_DIR`` pointing at its folder.
    tests : int, optional
    seed : int, optional
        The first test's seed (the others follow).

    Returns
    -------
    (Baseline, pathlib.Path)
        The baseline and where it was written.

    Raises
    ------
    RuntimeError
        If fewer than two tests converged.
    """
    kept = []
    for n in range(tests):
        s = seed + n
        result = run_test(variant, spread_valve(ValveFit(), s), seed=s, classify=False)
        if result.verdict != Verdict.UNCLASSIFIED:
            print(f"calibration test {n + 1}: {result.verdict}, not used: {'; '.join(result.reasons)}",
                  file=sys.stderr)
            continue
        kept.append(BaselineTest(result.features.af, result.features.a1, result.valve_id,
                                 BaselineSource.SIMULATED_RIG, result.started_at, "", **kept_figures(result)))
    if len(kept) < 2:
        raise RuntimeError(f"only {len(kept)} of {tests} calibration tests converged")
    baseline = baseline_from_tests(kept, station="second plant", command="tests.parts.second_plant")
    path = station_baseline_path(variant.name)
    write_baseline(path, baseline.to_toml(variant.name, "new valves on the second simulated plant"))
    return baseline, path


@contextmanager
def station_variant(folder: Path) -> Iterator[Variant]:
    """The variant brought up in ``folder`` (``EDC_BENCH_VARIANTS_DIR`` set meanwhile, restored after), calibrated.

    For pytest, set the variable with monkeypatch and call :func:`write_variant` and :func:`calibrate` instead.
    """
    before = os.environ.get("EDC_BENCH_VARIANTS_DIR")
    os.environ["EDC_BENCH_VARIANTS_DIR"] = str(folder)
    try:
        write_variant(folder)
        calibrate(load_variant(VARIANT_NAME))
        yield load_variant(VARIANT_NAME)
    finally:
        if before is None:
            os.environ.pop("EDC_BENCH_VARIANTS_DIR", None)
        else:
            os.environ["EDC_BENCH_VARIANTS_DIR"] = before


# --- the cases -------------------------------------------------------------------------------------------------

WORN = ValveFit(WORN_FRICTION_N, WORN_DAMPING_N_S_PER_MM, "worn")


class Expect:
    """What a case's tests must read as (checked by :func:`case_failures`)."""

    PASS_SOUND = "PASS, part none"  # new valve, sound pump (or faults below the limits)
    FAIL = "FAIL"  # worn valve, sound pump
    NOT_PASS = "not PASS"  # worn valve, faulty rack
    RACK = "rack"  # part RACK, valve not to be replaced
    RACK_OR_EVEN = "rack or valve-or-rack"  # uniform drag
    SENSOR = "sensor"  # part SENSOR, valve not to be replaced


@dataclass(frozen=True)
class Case:
    """One row of the table: a valve in a pump, run ``tests`` times with different seeds and valves.

    Attributes
    ----------
    name : str
    valve : ValveFit
    expect : str
        One of :class:`Expect`'s values.
    rack : RackShape
    sensor : SensorShape
    tests : int
    """

    name: str
    valve: ValveFit
    expect: str
    rack: RackShape = RackShape()
    sensor: SensorShape = SensorShape()
    tests: int = 5


BIND_N = 0.25  # peak of a local bind: 3.3 times the 0.075 N limit
CASES: tuple[Case, ...] = (
    Case("new valve, sound pump", ValveFit(), Expect.PASS_SOUND),
    Case("worn valve, sound pump", WORN, Expect.FAIL),
    Case("rack drag +0.15 N, +0.005 N s/mm", ValveFit(), Expect.RACK_OR_EVEN, RackShape(0.15, 0.005)),
    Case("rack bind 0.25 N at 7.5 mm (3 mm wide)", ValveFit(), Expect.RACK, RackShape(binds=((BIND_N, 7.5, 3.0),))),
    Case("rack bind 0.25 N at 12.5 mm (3 mm wide)", ValveFit(), Expect.RACK,
         RackShape(binds=((BIND_N, 12.5, 3.0),))),
    Case("rack friction rising 0.3 N from 4 to 16 mm (quadratic)", ValveFit(), Expect.RACK, RackShape(slope_n=0.3)),
    Case("bent rack: bind 0.6 N at 11 mm (8 mm wide)", ValveFit(), Expect.RACK, RackShape(binds=((0.6, 11.0, 8.0),))),
    Case("sensor gain +5 %", ValveFit(), Expect.SENSOR, sensor=SensorShape(gain=1.05)),
    Case("sensor gain -7 %", ValveFit(), Expect.SENSOR, sensor=SensorShape(gain=0.93)),
    Case("sensor zero +0.2 mm", ValveFit(), Expect.SENSOR, sensor=SensorShape(zero_mm=0.2)),
    Case("sensor S-kink 0.25 mm at 13.5 mm", ValveFit(), Expect.SENSOR, sensor=SensorShape(kink_mm=0.25)),
    Case("sensor noise 5x", ValveFit(), Expect.SENSOR, sensor=SensorShape(noise_scale=5.0)),
    Case("sensor dropouts to 0 mm rail, 1/s", ValveFit(), Expect.SENSOR, sensor=SensorShape(dropouts_per_s=1.0)),
    Case("sensor EMI spikes, 2/s", ValveFit(), Expect.SENSOR, sensor=SensorShape(spikes_per_s=2.0)),
    Case("worn valve, rack bind 0.25 N at 12.5 mm", WORN, Expect.NOT_PASS, RackShape(binds=((BIND_N, 12.5, 3.0),))),
    Case("below limit: sensor gain +1 %", ValveFit(), Expect.PASS_SOUND, sensor=SensorShape(gain=1.01)),
    Case("below limit: rack bind 0.02 N at 10 mm", ValveFit(), Expect.PASS_SOUND,
         RackShape(binds=((0.02, 10.0, 3.0),))),
)


@dataclass(frozen=True)
class TestReading:
    """What one test said."""

    seed: int
    verdict: str
    part: str
    action: str
    words: str
    reasons: tuple[str, ...]
    dropouts: int = 0
    spikes: int = 0


@dataclass
class CaseResult:
    """A case's tests, as read."""

    case: Case
    readings: list[TestReading] = field(default_factory=list)

    def count(self, attribute: str) -> dict[str, int]:
        """How many tests gave each value of ``attribute``."""
        out: dict[str, int] = {}
        for r in self.readings:
            out[getattr(r, attribute)] = out.get(getattr(r, attribute), 0) + 1
        return out

    @property
    def replace_told(self) -> int:
        """Tests that told the technician to replace the valve."""
        return sum(r.action == Action.REPLACE for r in self.readings)


def read_result(result: BenchResult, seed: int, rig: SimulatedRig | None = None) -> TestReading:
    """A test's verdict, part, advice and reasons."""
    part = result.judgement.part
    sensor = getattr(rig, "second_sensor", None)
    return TestReading(seed, str(result.verdict), str(part.part) if part is not None else "-",
                       str(result.advice.action), result.advice.words, tuple(result.reasons),
                       sensor.dropouts if sensor else 0, sensor.spikes if sensor else 0)


def run_case(variant: Variant, case: Case, index: int) -> CaseResult:
    """Run a case's tests (seeds ``1000 (index + 1) + n``), each with its own valve from the spread."""
    out = CaseResult(case)
    for n in range(case.tests):
        seed = 1000 * (index + 1) + n
        rig = build_rig(variant, spread_valve(case.valve, seed), case.rack, case.sensor, seed)
        result = run_on_simulated_rig(variant, rig, BenchOptions(valve_id=f"{case.name} #{n}"), seed=seed)
        out.readings.append(read_result(result, seed, rig))
    return out


def case_failures(result: CaseResult, share: float = 0.95) -> list[str]:
    """Why a case's tests do not read as its :class:`Expect` says (empty: they do)."""
    case, readings = result.case, result.readings
    n = len(readings)
    problems = []

    def share_of(ok: Sequence[bool]) -> float:
        return sum(ok) / n if n else 0.0

    if case.expect == Expect.PASS_SOUND:
        bad = [r for r in readings if r.verdict != Verdict.PASS or r.part != Part.NONE]
        if bad:
            problems.append(f"{len(bad)}/{n} not PASS with part none")
    elif case.expect == Expect.FAIL:
        if any(r.verdict != Verdict.FAIL for r in readings):
            problems.append(f"verdicts {result.count('verdict')}, all should be FAIL")
    elif case.expect == Expect.NOT_PASS:
        if any(r.verdict == Verdict.PASS for r in readings):
            problems.append(f"verdicts {result.count('verdict')}, none should be PASS")
    else:
        parts = {Expect.RACK: {Part.RACK}, Expect.RACK_OR_EVEN: {Part.RACK, Part.VALVE_OR_RACK},
                 Expect.SENSOR: {Part.SENSOR}}[case.expect]
        if share_of([r.part in parts for r in readings]) < share:
            problems.append(f"parts named {result.count('part')}: {' or '.join(sorted(parts))} "
                            f"in fewer than {share:.0%}")
        if case.expect != Expect.RACK_OR_EVEN and result.replace_told:
            problems.append(f"{result.replace_told}/{n} told to replace the (sound) valve")
    return problems


def run_all(variant: Variant, cases: Sequence[Case] = CASES) -> list[CaseResult]:
    """Every case, in order."""
    return [run_case(variant, case, index) for index, case in enumerate(cases)]


def _counts(counts: dict[str, int]) -> str:
    return ", ".join(f"{k} {v}" for k, v in sorted(counts.items(), key=lambda kv: -kv[1]))


def table(results: Sequence[CaseResult]) -> str:
    """The table: per case, tests, parts named, verdicts, replace-the-valve advice, and whether it reads as
    expected."""
    rows = [("case", "tests", "parts named", "verdicts", "replace", "expected", "ok")]
    for r in results:
        fails = case_failures(r)
        rows.append((r.case.name, str(len(r.readings)), _counts(r.count("part")), _counts(r.count("verdict")),
                     str(r.replace_told), r.case.expect, "yes" if not fails else "NO: " + "; ".join(fails)))
    widths = [max(len(row[k]) for row in rows) for k in range(len(rows[0]) - 1)]
    lines = ["  ".join(cell.ljust(w) for cell, w in zip(row, widths)) + "  " + row[-1] for row in rows]
    return "\n".join(lines)


def wrong_readings(results: Sequence[CaseResult]) -> str:
    """Every test of a case that does not read as expected, with its verdict, part, advice and reasons."""
    lines = []
    for r in results:
        if not case_failures(r):
            continue
        for t in r.readings:
            lines.append(f"{r.case.name} (seed {t.seed}, dropouts {t.dropouts}, spikes {t.spikes}): {t.verdict}, "
                         f"part {t.part}, {t.action}: {t.words}")
            lines.extend(f"    - {reason}" for reason in t.reasons)
    return "\n".join(lines)


def main() -> int:
    """Bring the pump type up on the second plant, run every case and print the table."""
    started = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="edc-second-plant-") as folder, station_variant(Path(folder)) as variant:
        baseline = load_baseline_figures(variant)
        print(baseline)
        results = run_all(variant)
    print(table(results))
    wrong = wrong_readings(results)
    if wrong:
        print("\ntests of the cases not read as expected:\n" + wrong)
    print(f"\n{sum(len(r.readings) for r in results) + 5} tests in {time.perf_counter() - started:.0f} s")
    return 0 if not wrong else 1


def load_baseline_figures(variant: Variant) -> str:
    """The station baseline the variant is judged against, in one line."""
    from edc_bench.verdict.baseline import load_baseline

    b = load_baseline(variant)
    motion = {key: b.motion(key) for key in ("a2_v_s2_per_mm", "a0_v_per_mm", "b_v")}
    shown = ", ".join(f"{k} {m[0]:.5g}" for k, m in motion.items() if m is not None)
    return (f"baseline of {variant.name} ({b.tests} tests, {b.path}): af {b.af_v:.4f} V (sd {b.af_sd_v:.4f}), "
            f"a1 {b.a1_v_s_per_mm:.5f} V s/mm (sd {b.a1_sd_v_s_per_mm:.5f}), {shown}")


if __name__ == "__main__":
    sys.exit(main())
