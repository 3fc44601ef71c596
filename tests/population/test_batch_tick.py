"""The batch path's tick is the loop's tick, to the bit (#54): fed the samples the loop's test read, the batch's
controller, reference, coil estimate and estimator send the drives the loop sent, every tick.

What the batch leaves out by design is the rig between them: the CAN codec's 1 mV and 1 um steps and the rig
firmware's timers, which split the plant's period at a heartbeat (the plant's step itself is the rig's, to the bit:
tests/sim/test_kernels.py). So the two are compared where they meet, the samples: the loop's are handed to the
batch's ticks in place of its own plant's (helpers.batch_drives_from_loop).
"""

from __future__ import annotations

import numpy as np
import pytest
from helpers import batch_drives_from_loop

from edc_bench.bench import run_simulated_test
from edc_bench.config import load_variant, with_changes
from edc_bench.control.design import ControllerDesign
from edc_bench.population import batch


@pytest.mark.parametrize(("variant_name", "valve", "seed"), [
    ("p-edc-default", "worn", 3),  # sensor noise, stiction, the RLS estimator
    pytest.param("p-edc-default", "new", 8, marks=pytest.mark.slow),
    pytest.param("p-edc-long", "faulty", 1, marks=pytest.mark.slow),
    pytest.param("gradient", "worn", 5, marks=pytest.mark.slow),  # the gradient law
])
def test_fed_the_loops_samples_the_batch_sends_the_loops_drives_to_the_bit(variant_name: str, valve: str,
                                                                           seed: int) -> None:
    changes: dict[str, object] = {"excitation": {"duration_s": 10.0}}
    if variant_name == "gradient":
        variant_name, changes["estimator"] = "p-edc-default", {"kind": "gradient"}
    variant = with_changes(load_variant(variant_name), changes, "test: 10 s")
    loop = run_simulated_test(variant, valve, seed, classify=False, check_gains=False)
    trace = {name: np.asarray(column) for name, column in loop.trace.items()}
    assert trace["reply_ok"].all() and (trace["sample_age_ticks"] == 1).all()  # each tick used the last one's sample
    drives = batch_drives_from_loop(variant, trace, seed)
    assert len(drives) == len(trace["drive_v"]) == 10_000
    differ = np.nonzero(drives != trace["drive_v"])[0]
    assert len(differ) == 0, f"first at tick {differ[0]}: loop {trace['drive_v'][differ[0]]!r}, batch {drives[differ[0]]!r}"


def test_a_batch_valves_reference_is_the_loops_to_the_bit() -> None:
    """The reference of each valve (its own measured start) is the loop controller's, at mid-tick and at the tick."""
    from edc_bench.control.fel import reference_table

    design = ControllerDesign.from_variant(load_variant())
    starts = np.array([0.0, 0.0131, 0.3491, 1.2345678])
    ours = batch._Reference(design, starts)
    tables = [reference_table(design.reference(float(s)), design.period_s, design.ticks) for s in starts]
    for k in range(0, design.ticks, 7):
        assert np.array(ours.at_mid_tick(k)).T.tolist() == [list(table[k][:4]) for table in tables], k
        assert ours.now(k).tolist() == [table[k][4] for table in tables], k
