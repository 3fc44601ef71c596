"""The simulated rig in-process on a python-can virtual bus, in lockstep."""

from __future__ import annotations

import can
import pytest

from edc_bench.config import Variant
from edc_bench.physics.valve import parse_valve_spec
from edc_bench.protocol import BENCH_CMD_ID, RIG_FEEDBACK_ID, RIG_HEARTBEAT_ID, Icd, Mode, RigState
from edc_bench.sim.rig import RigOptions, SimulatedRig


def _session(simulated_bench, icd: Icd, variant: Variant, seed: int, valve: str = "new", drive_v: float = 2.8,
             ticks: int = 800, options: RigOptions | None = None) -> list[tuple]:
    """Wait for READY, then send RUN commands in lockstep; return the replies."""
    bench, clock, _ = simulated_bench(variant, valve, seed, options=options, interface="virtual")
    rig = clock.rig  # the InProcessRig, stepped here by hand
    t, period = 0.0, 1e-3
    state = RigState.BOOT
    while state is not RigState.READY:
        t += period
        rig.advance_to(t)
        while (msg := bench.recv(0)) is not None:
            if msg.arbitration_id == RIG_HEARTBEAT_ID:
                state = icd.parse_heartbeat(msg.data).state
    replies = []
    for k in range(ticks):
        bench.send(can.Message(arbitration_id=BENCH_CMD_ID, is_extended_id=False, timestamp=t,
                               data=icd.make_bench_cmd(k % 256, Mode.RUN, drive_v, 10.0)))
        rig.service(t)
        msgs = [m for m in iter(lambda: bench.recv(0), None) if m.arbitration_id == RIG_FEEDBACK_ID]
        assert len(msgs) == 1
        assert msgs[0].timestamp == t  # simulated time on the bus
        replies.append(tuple(icd.parse_rig_feedback(msgs[0].data)))
        t += period
        rig.advance_to(t)
    return replies


def test_rig_on_virtual_bus_answers_every_command(simulated_bench, icd: Icd, variant: Variant) -> None:
    replies = _session(simulated_bench, icd, variant, seed=1)
    assert [r[0] for r in replies] == [k % 256 for k in range(len(replies))]
    first, last = replies[0], replies[-1]
    assert first[-2] < 0.1  # rack at its rest stop before the first drive
    drive_v = 2.8
    assert last[-2] == pytest.approx(10.0, abs=0.5)  # 2.8 V holds about mid-stroke
    assert last[-1] == pytest.approx(drive_v / variant.coil.resistance_ohm, rel=0.02)


def test_same_seed_same_run_other_seed_other_noise(simulated_bench, icd: Icd, variant: Variant) -> None:
    a = _session(simulated_bench, icd, variant, seed=3, ticks=300)
    b = _session(simulated_bench, icd, variant, seed=3, ticks=300)
    c = _session(simulated_bench, icd, variant, seed=4, ticks=300)
    assert a == b
    assert a != c


def test_noise_free_rig_reads_the_true_plant(simulated_bench, icd: Icd, variant: Variant) -> None:
    replies = _session(simulated_bench, icd, variant, seed=0, ticks=1500,
                       options=RigOptions(stiction=False, sensor_noise=False))
    rig = SimulatedRig(variant, parse_valve_spec("new", variant), options=RigOptions(stiction=False))
    band_mm = rig.plant_params.coulomb_friction_n / rig.plant_params.net_stiffness_n_per_mm
    assert abs(replies[-1][-2] - rig.plant_params.equilibrium_mm(2.8)) <= band_mm + 1e-3


def test_truth_is_exposed(variant: Variant) -> None:
    rig = SimulatedRig(variant, parse_valve_spec("worn", variant))
    assert rig.truth.af > 0 and rig.truth.a1 > 0
