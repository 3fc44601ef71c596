"""The simulated rig's compiled arithmetic: the exact step for a sliding valve, the Karnopp replay for a held one, a
sensor's reading.

(The whole batch against the simulated rig's plant: ``tests/identification/test_real_solenoids.py`` and
``tests/population/test_batch.py``; the same bits as before it was compiled: the shipped models rebuild byte for
byte, ``tests/learning/test_train.py``.)
"""

from __future__ import annotations

import numpy as np

from edc_bench.config import load_variant
from edc_bench.population.batch import QUANTA_PER_PERIOD, _VectorPlant
from edc_bench.population.rig_kernels import quantised_reading
from edc_bench.population.valves import draw_population


def _plant(n: int = 2) -> _VectorPlant:
    variant = load_variant("p-edc-default")
    return _VectorPlant(variant, draw_population(variant, n, 3), True, 1e-3)


def test_a_sliding_valve_takes_the_exact_step_to_the_bit() -> None:
    plant = _plant()
    plant.stuck[:] = False
    plant.x[:], plant.v[:], plant.i[:] = 5.0, 40.0, 1.0  # mid-stroke, sliding fast: no stick within the period
    drive_v = np.array([3.0, 2.5])
    pump, phi, gam = plant.pump, plant.phi, plant.gam
    coil_v = pump.amplifier_gain * np.minimum(np.maximum(drive_v, -pump.amplifier_limit_v), pump.amplifier_limit_v)
    f = -(pump.preload_n + plant.fc * 1.0)
    x_expected = phi[0] * 5.0 + phi[1] * 40.0 + phi[2] * 1.0 + gam[0] * coil_v + gam[1] * f
    i_expected = phi[8] * 1.0 + gam[4] * coil_v
    plant.advance_period(drive_v)
    assert np.array_equal(plant.x, x_expected)
    assert np.array_equal(plant.i, i_expected)
    assert not plant.stuck.any()


def test_a_valve_held_by_stiction_keeps_its_place_while_its_current_rises() -> None:
    plant = _plant(1)
    x0 = 3.0
    plant.x[:], plant.v[:], plant.i[:] = x0, 0.0, 0.0
    # the current that holds the rack exactly where it is: the spring and preload balanced, stiction not reached
    pump = plant.pump
    plant.i[:] = (pump.net_stiffness_n_per_mm * x0 + pump.preload_n) / pump.force_constant_n_per_a
    drive_v = np.array([plant.i[0] * plant.resistance_ohm[0] / pump.amplifier_gain])
    i_before = plant.i.copy()
    plant.advance_period(drive_v * 1.001)  # a touch more pull: within stiction
    assert plant.x[0] == x0 and plant.v[0] == 0.0 and plant.stuck[0]
    assert plant.i[0] > i_before[0]  # the coil's current still moves towards its new level
    # held for the period's every quantum: the current followed the quantum's step ten times
    i = i_before[0]
    coil_v = pump.amplifier_gain * drive_v[0] * 1.001
    for _ in range(QUANTA_PER_PERIOD):
        i = plant.phi_q[8, 0] * i + plant.gam_q[4, 0] * coil_v
    assert plant.i[0] == i


def test_a_reading_rounds_half_to_even_as_numpy_does() -> None:
    value = np.array([0.5, 1.5, 2.5, -0.5, -2.5, 3.2, -0.0, np.nan])  # in steps of 1: the halves go to the even
    assert np.array_equal(quantised_reading(value, 0.0, np.zeros(len(value)), 1.0),
                          np.array([0.0, 2.0, 2.0, -0.0, -2.0, 3.0, -0.0, np.nan]), equal_nan=True)
    rng = np.random.default_rng(5)
    value, noise = rng.uniform(0.0, 12.0, 1000), rng.normal(0.0, 2e-3, 1000)
    numpy_reading = np.round((value + 0.01 + noise) / 1e-3) * 1e-3
    assert np.array_equal(quantised_reading(value, 0.01, noise, 1e-3), numpy_reading)
