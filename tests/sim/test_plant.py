"""The plant against analysis: equilibrium, coil time constant, natural
frequency and damping of the linearised mechanics, stick-slip, stepping."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from edc_bench.config import Variant
from edc_bench.physics.parameters import PlantParameters
from edc_bench.physics.valve import parse_valve_spec, plant_parameters, with_friction
from edc_bench.sim.plant import Plant


@pytest.fixture()
def worn(variant: Variant) -> PlantParameters:
    return plant_parameters(variant, parse_valve_spec("worn", variant))


def _run(plant: Plant, seconds: float, drive_v: float | None = None) -> np.ndarray:
    if drive_v is not None:
        plant.set_drive_v(drive_v)
    out = np.empty(int(round(seconds / plant.quantum_s)))
    for k in range(len(out)):
        plant.advance(1)
        out[k] = plant.x_mm
    return out


def test_static_equilibrium_without_friction(any_variant: Variant) -> None:
    # a coil that does not warm: the warming moves the equilibrium (tested in test_coil_warms_*)
    params = replace(with_friction(plant_parameters(any_variant, parse_valve_spec("new", any_variant)), 0.0),
                     temperature_coefficient_per_k=0.0)
    target_mm = any_variant.rack.mid_stroke_mm
    drive_v = params.drive_for_position_v(target_mm)
    # from first principles: k_i k_A u / R = k' x + F_pre
    assert drive_v == pytest.approx(
        (params.net_stiffness_n_per_mm * target_mm + params.preload_n) * params.resistance_ohm
        / (params.force_constant_n_per_a * params.amplifier_gain))
    plant = Plant(params)
    _run(plant, 2.0, drive_v)
    assert plant.x_mm == pytest.approx(target_mm, abs=1e-6)
    assert plant.i_a == pytest.approx(params.amplifier_gain * drive_v / params.resistance_ohm, rel=1e-9)


def test_static_rest_with_friction_lies_in_the_friction_band(worn: PlantParameters) -> None:
    plant = Plant(worn)
    drive_v = worn.drive_for_position_v(10.0)
    _run(plant, 2.0, drive_v)
    band_mm = worn.stiction_friction_n / worn.net_stiffness_n_per_mm
    assert plant.stuck and plant.v_mm_s == 0.0
    assert abs(plant.x_mm - 10.0) <= band_mm
    # and the rest is not the frictionless one: friction held it short of 10 mm
    assert plant.x_mm != pytest.approx(10.0, abs=1e-3)


def test_rest_position_without_drive_is_the_safe_stop(worn: PlantParameters) -> None:
    plant = Plant(worn, position_mm=10.0)
    _run(plant, 1.0, 0.0)
    assert plant.x_mm == 0.0


def test_coil_time_constant(worn: PlantParameters) -> None:
    plant = Plant(replace(worn, coulomb_friction_n=50.0, stiction_friction_n=50.0))  # rack held
    tau_s = worn.inductance_h / worn.resistance_ohm
    plant.set_drive_v(2.0)
    n = int(round(tau_s / plant.quantum_s))
    plant.advance(n)
    expected = 2.0 / worn.resistance_ohm * (1.0 - math.exp(-n * plant.quantum_s / tau_s))
    assert plant.i_a == pytest.approx(expected, rel=1e-9)


@pytest.mark.parametrize("damping_ratio", [0.05, 0.2])
def test_natural_frequency_and_damping_of_linearised_plant(worn: PlantParameters, damping_ratio: float) -> None:
    k, m = worn.net_stiffness_n_per_mm, worn.mass_n_s2_per_mm
    c = damping_ratio * 2.0 * math.sqrt(k * m)
    params = with_friction(replace(worn, damping_n_s_per_mm=c, temperature_coefficient_per_k=0.0), 0.0)
    plant = Plant(params, position_mm=5.0)
    x_eq = params.equilibrium_mm(params.drive_for_position_v(10.0))
    plant.i_a = params.amplifier_gain * params.drive_for_position_v(10.0) / params.resistance_ohm
    plant.stuck = False
    plant.v_mm_s = 1e-9
    y = _run(plant, 0.6, params.drive_for_position_v(10.0)) - x_eq
    t = (np.arange(len(y)) + 1) * plant.quantum_s
    # damped period from upward zero crossings (interpolated)
    idx = np.nonzero((y[:-1] < 0) & (y[1:] >= 0))[0]
    crossings = t[idx] + (0 - y[idx]) / (y[idx + 1] - y[idx]) * plant.quantum_s
    wn = math.sqrt(k / m)
    wd_expected = wn * math.sqrt(1 - damping_ratio**2)
    wd_measured = 2 * math.pi / np.mean(np.diff(crossings))
    assert wd_measured == pytest.approx(wd_expected, rel=2e-3)
    # damping from the logarithmic decrement of successive maxima
    peaks = np.array([np.max(y[a:b]) for a, b in zip(idx[:-1], idx[1:], strict=True)])
    delta = np.mean(np.log(peaks[:-1] / peaks[1:]))
    zeta_measured = delta / math.sqrt(4 * math.pi**2 + delta**2)
    assert zeta_measured == pytest.approx(damping_ratio, rel=2e-2)
    assert plant.natural_frequency_rad_s() == pytest.approx(wn)
    assert plant.damping_ratio() == pytest.approx(damping_ratio)


def _ramp_sticks(params: PlantParameters) -> tuple[int, np.ndarray]:
    """Drive slowly from 8 to 10 mm; count stick events after the first breakaway."""
    plant = Plant(params)
    u0, u1 = params.drive_for_position_v(8.0), params.drive_for_position_v(10.0)
    _run(plant, 0.5, u0)
    before = plant.stick_events
    n = 8000
    xs = np.empty(n)
    for k in range(n):
        plant.set_drive_v(u0 + (u1 - u0) * k / n)
        plant.advance(10)
        xs[k] = plant.x_mm
    return plant.stick_events - before, xs


def test_stick_slip_present_with_stiction_and_absent_without(worn: PlantParameters) -> None:
    light = replace(worn, damping_n_s_per_mm=0.003)  # a lightly damped rack shows it clearly
    coulomb = with_friction(light, light.coulomb_friction_n)
    stiction = with_friction(light, light.coulomb_friction_n, 1.5 * light.coulomb_friction_n)
    sticks_coulomb, x_coulomb = _ramp_sticks(coulomb)
    sticks_stiction, x_stiction = _ramp_sticks(stiction)
    assert sticks_coulomb == 0
    assert sticks_stiction >= 3
    # stick-slip moves in jumps: long stretches at rest between fast slips
    rest_coulomb = np.mean(np.diff(x_coulomb) == 0.0)
    rest_stiction = np.mean(np.diff(x_stiction) == 0.0)
    assert rest_stiction > 0.5 > rest_coulomb


def test_whole_period_step_equals_fine_steps_away_from_reversals(worn: PlantParameters) -> None:
    coarse, fine = Plant(worn, position_mm=5.0), Plant(worn, position_mm=5.0)
    for plant in (coarse, fine):
        plant.set_drive_v(worn.drive_for_position_v(12.0))
        plant.advance(300)  # broken away, moving up
    assert not coarse.stuck and coarse.v_mm_s > 0
    coarse.advance(10)
    for _ in range(10):
        fine.advance(1)
    assert (coarse.x_mm, coarse.v_mm_s, coarse.i_a) == pytest.approx((fine.x_mm, fine.v_mm_s, fine.i_a), rel=1e-9)


def test_amplifier_limit_and_nan_drive(worn: PlantParameters) -> None:
    plant = Plant(worn)
    plant.set_drive_v(1000.0)
    assert plant.drive_v == worn.amplifier_limit_v
    plant.set_drive_v(math.nan)
    assert plant.drive_v == 0.0


def test_hard_stops(worn: PlantParameters) -> None:
    plant = Plant(worn)
    _run(plant, 0.5, worn.amplifier_limit_v)
    assert plant.x_mm == worn.stroke_mm


def test_coil_warms_with_its_losses_and_its_resistance_follows(worn: PlantParameters) -> None:
    """A held rack at 4 A: the coil's temperature follows the first-order model, step by step, and R with it."""
    from edc_bench.physics.coil import resistance_at_ohm, temperature_after_c
    from edc_bench.sim.plant import THERMAL_STEP_S

    plant = Plant(replace(worn, coulomb_friction_n=50.0, stiction_friction_n=50.0))  # rack held
    drive_v = 4.0 * worn.resistance_ohm / worn.amplifier_gain
    plant.set_drive_v(drive_v)
    steps = 100  # 10 s
    for _ in range(steps * 100):  # in command periods of 1 ms, as the rig advances it
        plant.advance(round(THERMAL_STEP_S / plant.quantum_s / 100))
    temp, r20 = worn.coil_temp_c, worn.resistance_20c_ohm
    for _ in range(steps):  # the same model by hand, with the steady current of each step
        r = resistance_at_ohm(r20, temp, worn.temperature_coefficient_per_k)
        current = worn.amplifier_gain * drive_v / r
        temp = temperature_after_c(temp, r * current**2, THERMAL_STEP_S, worn.ambient_c,
                                   worn.thermal_capacity_j_per_k, worn.thermal_resistance_k_per_w)
    assert plant.coil_temp_c == pytest.approx(temp, abs=0.05)
    assert plant.coil_temp_c - worn.coil_temp_c > 2.0  # about 11 W into 40 J/K: ~2.7 K in 10 s
    assert plant.resistance_ohm == pytest.approx(resistance_at_ohm(r20, plant.coil_temp_c,
                                                                   worn.temperature_coefficient_per_k), rel=1e-12)
    # and the current follows the warmer coil
    assert plant.i_a == pytest.approx(worn.amplifier_gain * drive_v / plant.resistance_ohm, rel=1e-3)
