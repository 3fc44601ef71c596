"""The batch path against the full loop: the same parameters within the documented tolerance, per seed."""

from __future__ import annotations

import numpy as np
import pytest

from edc_bench.bench import run_simulated_test
from edc_bench.config import load_variant
from edc_bench.physics.valve import parse_valve_spec
from edc_bench.population.batch import run_batch
from edc_bench.population.valves import draw_population
from edc_bench.engine.problems import Problem
from edc_bench.population.batch_stop import BatchStopRule
from edc_bench.sim.adapter import parse_adapter
from edc_bench.sim.pump_faults import SensorFault, parse_rack_fault, parse_sensor_fault

NAMES = ("a3", "a2", "a1", "a0", "b", "af")

BATCH_TOLERANCE = {"af": 0.01, "a1": 0.01, "a2": 0.03, "a0": 0.01, "b": 0.01, "a3": 1e-12}


# one case runs by default; tests/control/test_design.py checks the same agreement on the noise-free plant
@pytest.mark.parametrize(("variant_name", "valve", "adapter"), [
    pytest.param("p-edc-default", "new", None, marks=pytest.mark.slow),
    ("p-edc-default", "worn", None),
    pytest.param("p-edc-default", "faulty", None, marks=pytest.mark.slow),
    pytest.param("p-edc-long", "worn", None, marks=pytest.mark.slow),
    # the batch path's adapter model against the in-process rig's (14 s: in the slow pass)
    pytest.param("p-edc-default", "worn", "usb-fs", marks=pytest.mark.slow),
    pytest.param("p-edc-default", "new", "usb-fs", marks=pytest.mark.slow),
])
def test_batch_path_gives_the_full_loops_parameters(variant_name: str, valve: str, adapter: str | None) -> None:
    """Documented tolerance: af, a1, a0, b within 1 %, a2 within 3 % of the full loop (same valve, same link)."""
    variant = load_variant(variant_name)
    spec = parse_valve_spec(valve, variant)
    full = run_simulated_test(variant, spec, 1, check_gains=False, classify=False, adapter=adapter)
    batch = run_batch(variant, [spec], [1], adapter=parse_adapter(adapter) if adapter else None)
    for j, name in enumerate(NAMES):
        rel = abs(batch.parameters[0, j] / full.parameters[name].value - 1)
        assert rel <= BATCH_TOLERANCE[name], (name, rel)
    assert bool(batch.converged[0]) == full.converged
    assert batch.condition_number == pytest.approx(full.identification.condition_number, rel=0.05)
    assert np.allclose(batch.truth[0], list(full.truth))


@pytest.mark.parametrize(("rack", "sensor"), [
    ("bind", "long"),  # the rack's friction along the stroke and the sensor's reading in one pump: both paths
    pytest.param("drag", "none", marks=pytest.mark.slow),
    pytest.param("slope", "zero", marks=pytest.mark.slow),
    pytest.param("none", "bow", marks=pytest.mark.slow),
    pytest.param("none", "spikes", marks=pytest.mark.slow),
    pytest.param("none", "noisy", marks=pytest.mark.slow),
])
def test_a_batch_pump_with_a_faulty_rack_or_sensor_gives_the_full_loops_parameters(rack: str, sensor: str) -> None:
    """#67: the population engine gets the pumps' faults the simulated rig has (``--rack-fault``,
    ``--sensor-fault``), and finds what the loop finds of them within the documented tolerance (noise and spikes
    from streams of their own: a2 within 3 % as the noise allows); the truth stays the valve's own."""
    variant = load_variant()
    spec = parse_valve_spec("new", variant)
    full = run_simulated_test(variant, spec, 1, check_gains=False, classify=False, rack_fault=rack,
                              sensor_fault=sensor)
    batch = run_batch(variant, [spec], [1], rack_faults=parse_rack_fault(rack),
                      sensor_faults=parse_sensor_fault(sensor))
    sound = run_batch(variant, [spec], [1])
    for j, name in enumerate(NAMES):
        rel = abs(batch.parameters[0, j] / full.parameters[name].value - 1)
        assert rel <= BATCH_TOLERANCE[name], (name, rel)
    assert bool(batch.converged[0]) == full.converged
    assert np.allclose(batch.truth[0], list(full.truth)) and np.array_equal(batch.truth, sound.truth)
    assert not np.allclose(batch.parameters, sound.parameters, rtol=0.01)  # the fault moved what was identified
    assert np.isnan(batch.tripped_s).all()


@pytest.mark.slow  # 14 s
def test_a_batch_test_whose_sensor_trips_the_rig_is_aborted_as_the_loops() -> None:
    """A contact that drops out reads the sensor's zero: the loop drives the rack after it until the rig's
    over-current trips and the test aborts; the batch has no firmware of its own but checks every sample against
    the rig's limits, and its test is marked aborted where it tripped (not converged, not trusted, no certain
    verdict), with or without the early stop; its pump-mates run on untouched."""
    variant = load_variant()
    spec = parse_valve_spec("new", variant)
    full = run_simulated_test(variant, spec, 1, check_gains=False, classify=False, sensor_fault="dropouts")
    assert full.outcome.abort is not None and not full.converged
    faults = [parse_sensor_fault("dropouts"), SensorFault()]
    alone = run_batch(variant, [spec], [2])
    for stop in (None, BatchStopRule.shipped(variant)):
        batch = run_batch(variant, [spec, spec], [1, 2], sensor_faults=faults, stop=stop)
        assert 0.0 < batch.tripped_s[0] < 30.0 and np.isnan(batch.tripped_s[1])
        assert list(batch.converged) == [False, True]
        assert batch.problems[0] & Problem.ABORTED and not batch.trusted[0] and batch.trusted[1]
        if stop is None:
            assert np.array_equal(batch.parameters[1], alone.parameters[0])
        else:
            assert batch.stop is not None and not batch.stop.certain[0]
            assert batch.stop.time_s[0] == batch.tripped_s[0]


@pytest.mark.slow
def test_batch_is_deterministic_per_seed() -> None:
    variant = load_variant()
    valves = draw_population(variant, 6, 3)
    a = run_batch(variant, valves, list(range(6)))
    b = run_batch(variant, valves, list(range(6)))
    assert np.array_equal(a.parameters, b.parameters)


@pytest.mark.slow  # over 5 s each: the default suite's 5 minutes (CI's slow pass runs it)
def test_the_period_fit_taken_a_few_tests_at_a_time_gives_the_same_sums(monkeypatch: pytest.MonkeyPatch) -> None:
    """The rows are made and summed a slice of the tests at a time (for the CPU's cache): to the bit the same."""
    from edc_bench.population import batch

    variant = load_variant()
    valves = draw_population(variant, 5, 11)
    whole = run_batch(variant, valves, list(range(5)))
    # slices of 2 and 3 (a naive split, 4 and 1, would sum the lone test in another order)
    monkeypatch.setattr(batch._RowFeeder, "TESTS_AT_A_TIME", 4)
    sliced = run_batch(variant, valves, list(range(5)))
    for name in whole.periods.acc._SUMS:
        assert np.array_equal(getattr(whole.periods.acc, name), getattr(sliced.periods.acc, name)), name
    assert np.array_equal(whole.parameters, sliced.parameters)
