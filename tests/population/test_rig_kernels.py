"""The simulated rig's compiled arithmetic: the exact step for a sliding valve, the Karnopp replay for a held one, a
sensor's reading.

(The whole batch against the simulated rig's plant: ``tests/identification/test_real_solenoids.py`` and
``tests/population/test_batch.py``; the same bits as before it was compiled: the shipped models rebuild byte for
byte, ``tests/learning/test_train.py``.)
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from edc_bench.config import load_variant
from edc_bench.population.batch import QUANTA_PER_PERIOD, _VectorPlant
from edc_bench.population.rig_kernels import quantised_reading
from edc_bench.population.valves import draw_population
from edc_bench.sim.plant import STICK_SPEED_MM_S


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
                          np.array([0.0, 2.0, 2.0, 0.0, -2.0, 3.0, 0.0, np.nan]), equal_nan=True)
    rng = np.random.default_rng(5)
    value, noise = rng.uniform(0.0, 12.0, 1000), rng.normal(0.0, 2e-3, 1000)
    numpy_reading = np.round((value + 0.01 + noise) / 1e-3) * 1e-3
    assert np.array_equal(quantised_reading(value, 0.01, noise, 1e-3), numpy_reading)


# -- the numpy version the kernels replaced, kept as the oracle of "the same to the bit" ---------------------------
# (the Stribeck curve's exponential taken elementwise from the C library, as the kernels take it)


def _numpy_propagate(plant, phi, gam, x, v, i, coil_v, sign, fc, fs, dt_s):  # noqa: ANN001, ANN202
    pump = plant.pump
    if pump.linear:
        f = -(pump.preload_n + fc * sign)
    else:
        friction = fc
        if pump.stribeck_velocity_mm_s > 0.0:
            q = v / pump.stribeck_velocity_mm_s
            friction = fc + (fs - fc) * np.array([math.exp(t) for t in -(q * q)])
        mid_mm = x + 0.5 * dt_s * v
        f = (pump.force_constant_n_per_a * pump.force_constant_slope_per_mm * (mid_mm - pump.force_constant_mid_mm)
             * i - (pump.preload_n + friction * sign))
    xn = phi[0] * x + phi[1] * v + phi[2] * i + gam[0] * coil_v + gam[1] * f
    vn = phi[3] * x + phi[4] * v + phi[5] * i + gam[2] * coil_v + gam[3] * f
    return xn, vn, phi[8] * i + gam[4] * coil_v


def _numpy_fine(plant, x, v, i, stuck, coil_v, quanta):  # noqa: ANN001, ANN202
    pump = plant.pump
    k, ki, fpre, stroke = pump.net_stiffness_n_per_mm, pump.force_constant_n_per_a, pump.preload_n, pump.stroke_mm
    slope, x_mid = pump.force_constant_slope_per_mm, pump.force_constant_mid_mm
    phi, gam = plant.phi_q, plant.gam_q
    for step in range(int(quanta.max(initial=0))):
        net = ki * (1.0 + slope * (x - x_mid)) * i - k * x - fpre
        hold = stuck & ((np.abs(net) <= plant.fs) | ((x <= 0.0) & (net <= 0.0)) | ((x >= stroke) & (net >= 0.0)))
        sign = np.where(stuck, np.where(net > 0.0, 1.0, -1.0), np.where(v > 0.0, 1.0, -1.0))
        xn, vn, i_n = _numpy_propagate(plant, phi, gam, x, v, i, coil_v, sign, plant.fc, plant.fs,
                                       plant._period_s / QUANTA_PER_PERIOD)
        i_hold = phi[8] * i + gam[4] * coil_v
        reversed_ = vn * sign <= 0.0
        frac = np.where(v != vn, v / np.where(v != vn, v - vn, 1.0), 0.0)
        x_rev = x + frac * (xn - x)
        pull = ki * (1.0 + slope * (xn - x_mid)) * i_n
        slow = ~reversed_ & (np.abs(vn) < STICK_SPEED_MM_S) & (np.abs(pull - k * xn - fpre) <= plant.fs)
        new_stuck = reversed_ | slow
        xn = np.where(reversed_, x_rev, xn)
        vn = np.where(new_stuck, 0.0, vn)
        low, high = xn <= 0.0, xn >= stroke
        xn = np.where(low, 0.0, np.where(high, stroke, xn))
        vn = np.where(low | high, 0.0, vn)
        new_stuck = new_stuck | low | high
        done = step >= quanta
        xn, vn, i_n, new_stuck = np.where(done, x, xn), np.where(done, v, vn), np.where(done, i, i_n), \
            np.where(done, stuck, new_stuck)
        hold = hold & ~done
        x, v, i, stuck = np.where(hold, x, xn), np.where(hold, 0.0, vn), np.where(hold, i_hold, i_n), \
            np.where(hold, True, new_stuck)
    return x, v, i, stuck


def _numpy_period(plant, drive_v):  # noqa: ANN001, ANN202
    """One period of every valve, as the batch path stepped it in numpy (no adapter: every valve a whole period)."""
    pump = plant.pump
    coil_v = pump.amplifier_gain * np.minimum(np.maximum(drive_v, -pump.amplifier_limit_v), pump.amplifier_limit_v)
    sign = np.where(plant.v > 0.0, 1.0, -1.0)
    xn, vn, i_n = _numpy_propagate(plant, plant.phi, plant.gam, plant.x, plant.v, plant.i, coil_v, sign, plant.fc,
                                   plant.fs, plant._period_s)
    ok = ~plant.stuck & (vn * sign > STICK_SPEED_MM_S) & (xn > 0.0) & (xn < pump.stroke_mm)
    fx, fv, fi, fstuck = _numpy_fine(plant, plant.x, plant.v, plant.i, plant.stuck, coil_v,
                                     np.full(len(plant.x), QUANTA_PER_PERIOD))
    return np.where(ok, xn, fx), np.where(ok, vn, fv), np.where(ok, i_n, fi), np.where(ok, plant.stuck, fstuck)


@pytest.mark.parametrize("variant_name", ["p-edc-default", "p-edc-hard"])
def test_the_compiled_step_is_the_numpy_step_to_the_bit(variant_name: str) -> None:
    variant = load_variant(variant_name)
    plant = _VectorPlant(variant, draw_population(variant, 8, 7), True, 1e-3)
    rng = np.random.default_rng(1)
    held, stops = 0, 0
    for k in range(600):  # reversals at several frequencies, noise, two drives past the limit (the stops)
        drive_v = 2.0 + 1.5 * np.sin(2 * np.pi * rng.uniform(1.0, 9.0, 8) * k * 1e-3) + rng.normal(0.0, 0.8, 8)
        drive_v += 40.0 if k == 50 else -40.0 if k == 300 else 0.0
        expected = _numpy_period(plant, drive_v)
        plant.advance_period(drive_v)
        for got, want in zip((plant.x, plant.v, plant.i, plant.stuck), expected):
            assert np.array_equal(got, want), f"tick {k}"
        plant.add_heat(1e-3)
        held += int(plant.stuck.sum())
        stops += int(((plant.x == 0.0) | (plant.x == plant.pump.stroke_mm)).sum())
    assert held > 0 and stops > 0  # the run went through the Karnopp replay and the stops, not only the exact step


def test_the_kernels_run_where_no_cache_folder_can_be_written(tmp_path) -> None:  # noqa: ANN001
    import os
    import subprocess
    import sys

    not_a_folder = tmp_path / "a file"
    not_a_folder.write_text("")  # a folder under it cannot be made, not even by root
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"} | {"EDC_BENCH_CACHE_DIR": str(not_a_folder)}
    probe = ("import numpy as np; from edc_bench.population import rig_kernels as k; "
             "print(k._CACHE, k.quantised_reading(np.array([1.26]), 0.0, np.zeros(1), 0.1)[0])")
    done = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, env=env, check=False)
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == ["False", "1.3"]


_BATCH = """
import sys
if sys.argv[1] == "without":
    sys.modules["numba"] = None  # as on a machine numba has no wheel for: its import fails
import numpy as np
from edc_bench.config import load_variant
from edc_bench.population import rig_kernels
from edc_bench.population.batch import run_batch
from edc_bench.population.valves import draw_population

variant = load_variant("p-edc-default")
variant = variant.model_copy(update={"excitation": variant.excitation.model_copy(update={"duration_s": 4.0})})
result = run_batch(variant, draw_population(variant, 2, 5), [1, 2])
print(rig_kernels.COMPILED, result.feature("af").tobytes().hex(), result.feature("a1").tobytes().hex())
"""


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
