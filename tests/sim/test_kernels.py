"""The simulated rig's arithmetic, one definition (:mod:`edc_bench.sim.kernels`): the exact step for a sliding valve,
the Karnopp replay for a held one, a sensor's reading; the batch path's N valves held to N rig plants to the bit.

(The whole batch against the simulated rig's loop: ``tests/identification/test_real_solenoids.py`` and
``tests/population/test_batch.py``; the same bits as before it was compiled: the shipped models rebuild byte for
byte, ``tests/learning/test_train.py``.)
"""

from __future__ import annotations


import numpy as np
import pytest

from edc_bench.config import load_variant
from edc_bench.population.batch import QUANTA_PER_PERIOD, _VectorPlant
from edc_bench.population.valves import draw_population
from edc_bench.physics.valve import plant_parameters
from edc_bench.sim.kernels import compiled
from edc_bench.sim.plant import Plant
from edc_bench.sim.pump_faults import RACK_PRESETS, RackFault


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
    assert np.array_equal(compiled().quantised_reading(value, 0.0, np.zeros(len(value)), 1.0),
                          np.array([0.0, 2.0, 2.0, 0.0, -2.0, 3.0, 0.0, np.nan]), equal_nan=True)
    rng = np.random.default_rng(5)
    value, noise = rng.uniform(0.0, 12.0, 1000), rng.normal(0.0, 2e-3, 1000)
    numpy_reading = np.round((value + 0.01 + noise) / 1e-3) * 1e-3
    assert np.array_equal(compiled().quantised_reading(value, 0.01, noise, 1e-3), numpy_reading)


# -- the oracle: the simulated rig's own plant, one valve at a time ---------------------------------------------------


def _assert_same_state(batch: _VectorPlant, rigs: list[Plant], k: int) -> None:
    """The batch's valves are the rig plants to the bit after tick ``k``."""
    for got, want in zip((batch.x, batch.v, batch.i, batch.stuck),
                         zip(*[(p.x_mm, p.v_mm_s, p.i_a, p.stuck) for p in rigs])):
        assert np.array_equal(got, np.array(want)), f"tick {k}"


def _drives(rng: np.random.Generator, k: int, n: int) -> np.ndarray:
    """Reversals at several frequencies, noise, and two drives past the limit (the stops)."""
    drive_v = 2.0 + 1.5 * np.sin(2 * np.pi * rng.uniform(1.0, 9.0, n) * k * 1e-3) + rng.normal(0.0, 0.8, n)
    return drive_v + (40.0 if k == 50 else -40.0 if k == 300 else 0.0)


@pytest.mark.parametrize("variant_name", ["p-edc-default", "p-edc-hard"])
def test_the_batchs_valves_step_as_the_simulated_rigs_plant_to_the_bit(variant_name: str) -> None:
    """#54: the plant is stepped by one definition; N valves in the batch are N rig plants, tick after tick, through
    exact steps, the Karnopp replay, the stops and the coil's warming (a Stribeck pump with its varying pull too).
    Before, the batch's kernel and the rig's plant were two copies, and a third (numpy) was the tests' oracle."""
    variant = load_variant(variant_name)
    valves = draw_population(variant, 8, 7)
    batch = _VectorPlant(variant, valves, True, 1e-3)
    rigs = [Plant(plant_parameters(variant, valve, stiction=True), quantum_s=1e-3 / QUANTA_PER_PERIOD)
            for valve in valves]
    rng = np.random.default_rng(1)
    held = stops = 0
    for k in range(600):
        drive_v = _drives(rng, k, len(valves))
        batch.advance_period(drive_v)
        batch.add_heat(1e-3)
        for plant, drive in zip(rigs, drive_v):
            plant.set_drive_v(float(drive))
            plant.advance(QUANTA_PER_PERIOD)
        _assert_same_state(batch, rigs, k)
        held += int(batch.stuck.sum())
        stops += int(((batch.x == 0.0) | (batch.x == batch.pump.stroke_mm)).sum())
    assert held > 0 and stops > 0  # the run went through the Karnopp replay and the stops, not only the exact step
    assert sum(p.stick_events for p in rigs) > 0
    assert not np.array_equal(batch.resistance_ohm, [p.params.resistance_ohm for p in rigs])  # the coils warmed


def test_the_batchs_pumps_each_with_its_own_rack_step_as_the_rig_plant_of_that_pump() -> None:
    """#67: the batch's valves sit in pumps whose racks differ (a bind, a slope, a dragging guide, a sound one):
    each steps as the simulated rig's plant of that valve in that pump, to the bit (the rig's plant takes the rack
    as :meth:`RackFault.applied` gives it)."""
    variant = load_variant("p-edc-default")
    valves = draw_population(variant, 5, 7)
    racks = [RACK_PRESETS["bind"], RackFault(), RACK_PRESETS["slope"], RACK_PRESETS["drag"],
             RackFault(bind_n=0.4, bind_at_mm=9.0, bind_width_mm=2.0, slope_n_per_mm=-0.01)]
    batch = _VectorPlant(variant, valves, True, 1e-3, racks)
    ratio = variant.valve.stiction_ratio
    rigs = [Plant(rack.applied(plant_parameters(variant, valve, stiction=True), ratio),
                  quantum_s=1e-3 / QUANTA_PER_PERIOD) for valve, rack in zip(valves, racks)]
    sound = _VectorPlant(variant, valves, True, 1e-3)
    rng = np.random.default_rng(3)
    for k in range(600):
        drive_v = _drives(rng, k, len(valves))
        for plant in (batch, sound):
            plant.advance_period(drive_v)
            plant.add_heat(1e-3)
        for plant, drive in zip(rigs, drive_v):
            plant.set_drive_v(float(drive))
            plant.advance(QUANTA_PER_PERIOD)
        _assert_same_state(batch, rigs, k)
    assert batch.x[1] == sound.x[1]  # the sound pump's valve as in a sound batch
    assert all(batch.x[j] != sound.x[j] for j in (0, 2, 3, 4))  # each rack moved its valve


def test_steps_of_part_of_a_period_are_the_rig_plants_too() -> None:
    """The batch's steps of a few quanta (an adapter's timing moves the drive mid-period) against the rig's plant
    stepped the same quanta (the coils kept at one temperature: the batch warms them a period at a time, and a
    rig plant advanced by uneven quanta takes its thermal steps elsewhere in the period)."""
    variant = load_variant("p-edc-default")
    variant = variant.model_copy(update={"coil": variant.coil.model_copy(update={"temperature_coefficient_per_k": 0.0})})
    valves = draw_population(variant, 6, 2)
    batch = _VectorPlant(variant, valves, True, 1e-3)
    rigs = [Plant(plant_parameters(variant, valve, stiction=True), quantum_s=1e-3 / QUANTA_PER_PERIOD)
            for valve in valves]
    rng = np.random.default_rng(4)
    for k in range(300):
        drive_v = _drives(rng, k, len(valves))
        quanta = rng.integers(0, QUANTA_PER_PERIOD + 1, len(valves))
        batch.advance_quanta(quanta, drive_v)
        for plant, drive, m in zip(rigs, drive_v, quanta):
            plant.set_drive_v(float(drive))
            plant.advance(int(m))
        assert np.array_equal(batch.x, [p.x_mm for p in rigs]), f"tick {k}"
        assert np.array_equal(batch.v, [p.v_mm_s for p in rigs]) and np.array_equal(batch.i, [p.i_a for p in rigs])


def test_the_kernels_run_where_no_cache_folder_can_be_written(tmp_path) -> None:  # noqa: ANN001
    import os
    import subprocess
    import sys

    not_a_folder = tmp_path / "a file"
    not_a_folder.write_text("")  # a folder under it cannot be made, not even by root
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"} | {"EDC_BENCH_CACHE_DIR": str(not_a_folder)}
    probe = ("import numba, numpy as np; from edc_bench.sim import kernels as k; ns = k.compiled(); "
             "print(k._cache_folder(numba), ns.compiled, ns.quantised_reading(np.array([1.26]), 0.0, np.zeros(1), 0.1)[0])")
    done = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, env=env, check=False)
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == ["False", "True", "1.3"]


_BATCH = """
import sys
if sys.argv[1] == "without":
    sys.modules["numba"] = None  # as on a machine numba has no wheel for: its import fails
import numpy as np
from edc_bench.config import load_variant
from edc_bench.sim import kernels
from edc_bench.population.batch import run_batch
from edc_bench.population.valves import draw_population

variant = load_variant("p-edc-default")
variant = variant.model_copy(update={"excitation": variant.excitation.model_copy(update={"duration_s": 4.0})})
result = run_batch(variant, draw_population(variant, 2, 5), [1, 2])
print(kernels.compiled().compiled, result.feature("af").tobytes().hex(), result.feature("a1").tobytes().hex())
"""


@pytest.mark.slow  # seconds: CI's slow pass runs it (the default suite stays under 5 minutes on CI)
def test_the_batch_path_runs_without_numba_to_the_same_bits_and_says_it_is_slower() -> None:
    """#54: the package installs and runs where numba has no wheel (pyproject installs it only where it has)."""
    import subprocess
    import sys

    runs = {how: subprocess.run([sys.executable, "-c", _BATCH, how], capture_output=True, text=True, timeout=600)
            for how in ("with", "without")}
    for how, done in runs.items():
        assert done.returncode == 0, (how, done.stderr[-2000:])
    compiled, *with_numba = runs["with"].stdout.split()
    python, *without_numba = runs["without"].stdout.split()
    assert (compiled, python) == ("True", "False")
    assert without_numba == with_numba  # the same arithmetic, to the bit (a linear pump)
    assert "numba is not installed" in runs["without"].stderr and "slower" in runs["without"].stderr
    assert "numba" not in runs["with"].stderr
