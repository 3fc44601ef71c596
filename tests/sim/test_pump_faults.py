"""The simulated pump's faulty rack and rack-travel sensor (``--rack-fault``, ``--sensor-fault``): their specs and
their physics."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from edc_bench.config import load_variant
from edc_bench.errors import ConfigError
from edc_bench.physics.valve import nominal_plant
from edc_bench.sim.plant import Plant
from edc_bench.sim.pump_faults import (
    RACK_PRESETS,
    FaultySensorReading,
    RackFault,
    SensorFault,
    SensorFaultReadings,
    parse_rack_fault,
    parse_sensor_fault,
)


def test_a_spec_is_a_preset_refined_by_pairs_and_says_itself_back() -> None:
    fault = parse_rack_fault("bind,bind_at_mm=8")
    assert fault == dataclasses.replace(RACK_PRESETS["bind"], bind_at_mm=8.0)
    assert parse_rack_fault(fault.spec()) == fault
    assert parse_sensor_fault("gain=1.05,offset_mm=0.2") == SensorFault(gain=1.05, offset_mm=0.2)
    assert parse_sensor_fault("none").none and parse_rack_fault("").none
    assert SensorFault().spec() == "none"


@pytest.mark.parametrize(("text", "message"), [
    ("bind,bind_n=x", "bind_n = 'x' is not a number"),
    ("bind_n=50", "bind_n = 50 is outside 0..20"),
    ("twist", "'twist' is not a fault; give drag, dry, bind, bent, slope"),
    ("bind_n=1,bind_n=2", "bind_n is given twice"),
    ("bend_n=1", "unknown key 'bend_n'"),
    ("drag,bind", "'drag,bind': 'bind' is not a fault"),  # one preset, first
])
def test_a_bad_rack_spec_is_refused_in_one_line_naming_what_is_wrong(text: str, message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        parse_rack_fault(text)


def test_a_bad_sensor_spec_is_refused_in_one_line() -> None:
    with pytest.raises(ConfigError, match=r"--sensor-fault 'gain=3': gain = 3 is outside 0.5..1.5"):
        parse_sensor_fault("gain=3")
    with pytest.raises(ConfigError, match="nan"):
        parse_sensor_fault("offset_mm=nan")


def test_a_dragging_rack_adds_to_the_valves_friction_and_damping_a_bind_to_its_place() -> None:
    variant = load_variant("p-edc-default")
    valve = nominal_plant(variant)
    drag = RackFault(drag_n=0.3, drag_damping_n_s_per_mm=0.004).applied(valve, stiction_ratio=1.3)
    assert drag.coulomb_friction_n == pytest.approx(valve.coulomb_friction_n + 0.3)
    assert drag.stiction_friction_n == pytest.approx(valve.stiction_friction_n + 0.39)
    assert drag.damping_n_s_per_mm == pytest.approx(valve.damping_n_s_per_mm + 0.004)
    assert drag.linear  # even drag keeps the linear model
    bind = RackFault(bind_n=1.0, bind_at_mm=12.0, bind_width_mm=1.0).applied(valve, 1.3)
    assert not bind.linear
    assert bind.rack_friction_n(12.0) == pytest.approx(1.0)
    assert bind.rack_friction_n(13.0) == pytest.approx(math.exp(-1.0))
    assert bind.rack_friction_n(8.0) < 1e-6
    slope = RackFault(slope_n_per_mm=0.01).applied(valve, 1.3)
    assert slope.rack_friction_n(0.0) == 0.0 and slope.rack_friction_n(15.0) == pytest.approx(0.15)
    assert RackFault().applied(valve, 1.3) is valve


def _held(params, position_mm: float, net_force_n: float) -> float:
    """Where a rack resting at ``position_mm`` is after 50 ms with a coil current that pushes it by
    ``net_force_n`` beyond spring and preload (the coil settled first)."""
    plant = Plant(params, position_mm=position_mm)
    k_net = params.spring_n_per_mm - params.magnetic_stiffness_n_per_mm
    current_a = (k_net * position_mm + params.preload_n + net_force_n) / params.force_constant_n_per_a
    plant.i_a = current_a
    plant.set_drive_v(current_a * params.resistance_ohm / params.amplifier_gain)
    plant.advance(500)
    return plant.x_mm


def test_a_bind_holds_the_rack_at_its_place_with_a_force_that_moves_it_elsewhere() -> None:
    variant = load_variant("p-edc-default")
    valve = nominal_plant(variant)
    bound = RackFault(bind_n=1.0, bind_at_mm=12.0).applied(valve, 1.3)
    push = valve.stiction_friction_n + 0.5  # beyond the valve's breakaway, within the bind's
    assert _held(bound, 12.0, push) == pytest.approx(12.0, abs=1e-9)  # stuck at the bind
    assert _held(bound, 6.0, push) > 6.05  # free away from it
    assert _held(valve, 12.0, push) > 12.05  # and free there without it


def test_the_faulty_sensors_reading_follows_its_formula_and_its_events_their_rates() -> None:
    stroke = 20.0
    exact = FaultySensorReading(SensorFault(gain=1.08, offset_mm=0.3, bow_mm=0.2), stroke, np.random.default_rng(1))
    for x in (0.0, 5.0, 10.0, 20.0):
        u = x / stroke
        assert exact.read(x, 0.0) == pytest.approx(1.08 * x + 0.3 + 0.2 * 4 * u * (1 - u))
    noisy = FaultySensorReading(SensorFault(dropouts_per_s=2.0, dropout_ms=3.0, spikes_per_s=5.0), stroke,
                                np.random.default_rng(2))
    readings = np.array([noisy.read(10.0, k * 1e-3) for k in range(20_000)])  # 20 s at 1 kHz
    assert 25 <= noisy.dropouts <= 55 and 70 <= noisy.spikes <= 130  # Poisson: 40 and 100 expected
    assert (readings == 0.0).sum() >= 2.5 * noisy.dropouts  # each dropout reads the zero for about 3 ms
    assert np.sum(np.abs(readings - 10.0) == 0.5) == noisy.spikes  # each spike one reading, 0.5 mm off
    again = FaultySensorReading(noisy.fault, stroke, np.random.default_rng(2))
    assert np.array_equal(readings, [again.read(10.0, k * 1e-3) for k in range(20_000)])  # seeded


def test_the_batch_paths_sensors_read_by_the_one_sensors_formula_and_its_events() -> None:
    """The batch's N sensors (:class:`SensorFaultReadings`) against the loop's one (:class:`FaultySensorReading`):
    the same reading where no event falls, to the last bits of numpy's tanh; the same events at their rates, each
    sensor from its own stream, a sound one among them reading the rack as it is."""
    stroke = 20.0
    shapes = [SensorFault(gain=1.08, offset_mm=0.3, bow_mm=0.2), SensorFault(step_mm=0.3, step_at_mm=7.0),
              SensorFault(), SensorFault(gain=0.93, bow_mm=-0.1, step_mm=-0.2, step_at_mm=15.0, step_width_mm=2.0)]
    many = SensorFaultReadings(shapes, stroke, [1, 2, 3, 4])
    ones = [FaultySensorReading(f, stroke, np.random.default_rng(9)) for f in shapes]
    for x in np.linspace(0.0, stroke, 41):
        got = many.read(np.full(len(shapes), x), 0.0)
        assert got == pytest.approx([one.read(float(x), 0.0) for one in ones], abs=1e-12)
        assert got[2] == x

    eventful = SensorFault(dropouts_per_s=2.0, dropout_ms=3.0, spikes_per_s=5.0)
    many = SensorFaultReadings([eventful, SensorFault(), eventful], stroke, [5, 6, 7])
    readings = np.array([many.read(np.full(3, 10.0), k * 1e-3) for k in range(20_000)])  # 20 s at 1 kHz
    assert list(many.dropouts[[0, 2]]) != [0, 0] and many.dropouts[1] == 0 and many.spikes[1] == 0
    for j in (0, 2):
        assert 25 <= many.dropouts[j] <= 55 and 70 <= many.spikes[j] <= 130  # Poisson: 40 and 100 expected
        assert (readings[:, j] == 0.0).sum() >= 2.5 * many.dropouts[j]  # each dropout reads zero for about 3 ms
        assert np.sum(np.abs(readings[:, j] - 10.0) == 0.5) == many.spikes[j]  # each spike one reading 0.5 mm off
    assert not np.array_equal(readings[:, 0], readings[:, 2])  # each its own stream
    assert np.all(readings[:, 1] == 10.0)


def test_the_batch_paths_sensors_read_in_part_keep_each_sensors_stream() -> None:
    """Through a CAN adapter the batch reads a few valves at a time, and valves leave as their tests stop: each
    sensor's noise and events stay its own however the batch reads it."""
    stroke = 20.0
    faults = [SensorFault(noise_sd_mm=0.02, spikes_per_s=20.0), SensorFault(noise_sd_mm=0.01, dropouts_per_s=10.0),
              SensorFault(noise_sd_mm=0.03)]
    whole = SensorFaultReadings(faults, stroke, [1, 2, 3], block=7)
    parts = SensorFaultReadings(faults, stroke, [1, 2, 3], block=7)
    x = np.array([5.0, 10.0, 15.0])
    for k in range(200):
        t_s = k * 1e-3
        expected = whole.read(x, t_s)
        got = np.concatenate([parts.read(x[[0, 2]], t_s, np.array([0, 2])), parts.read(x[[1]], t_s, np.array([1]))])
        assert np.array_equal(got, expected[[0, 2, 1]])
    whole.take(np.array([1, 2]))
    parts.take(np.array([1, 2]))
    for k in range(200, 300):
        assert np.array_equal(parts.read(x[1:], k * 1e-3), whole.read(x[1:], k * 1e-3))


def test_a_bind_of_no_force_changes_nothing_wherever_it_is_put() -> None:
    """The kernels' rack term adds exactly nothing without a bind or a slope, in the non-linear branch too (the
    stored records' replay to the bit, tests/bench/test_replay.py, holds the rest)."""
    variant = load_variant("p-edc-hard")  # the non-linear branch (gain variation, Stribeck) takes the rack term
    params = nominal_plant(variant)
    same = RackFault().applied(params, 1.3)
    a, b = Plant(params), Plant(dataclasses.replace(same, rack_bind_at_mm=5.0, rack_bind_width_mm=3.0))
    for k in range(3000):
        drive = 2.0 + 1.5 * math.sin(k * 0.004)
        a.set_drive_v(drive)
        b.set_drive_v(drive)
        a.advance(10)
        b.advance(10)
    assert (a.x_mm, a.v_mm_s, a.i_a) == (b.x_mm, b.v_mm_s, b.i_a)


@pytest.mark.parametrize(("argv", "message"), [
    (["test", "--rack-fault", "twist"], "argument --rack-fault: 'twist' is not a fault; give drag, dry, bind"),
    (["test", "--rack-fault", "bind,twist"], "argument --rack-fault: 'bind,twist': 'twist' is not a fault"),
    (["rig", "--listen", "127.0.0.1:0", "--sensor-fault", "gain=2"], "gain = 2 is outside 0.5..1.5"),
    (["session", "--sensor-fault", "spikes_per_s=-1"], "spikes_per_s = -1 is outside 0..100"),
])
def test_a_bad_fault_on_the_command_line_is_one_line_and_exit_2(argv: list[str], message: str,
                                                                 capsys: pytest.CaptureFixture[str]) -> None:
    from helpers import run_cli

    code, out, err = run_cli(argv, capsys)
    assert code == 2 and message in err and "Traceback" not in err, err
