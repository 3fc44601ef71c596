"""The controller's arithmetic is written once (edc_bench.control.law): the loop, replay, the batch path and the
benchmark's floor all run it, so changing one detail of it changes all four."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from helpers import batch_drives_from_loop

from edc_bench.bench import run_simulated_test
from edc_bench.config import Variant, with_changes
from edc_bench.control import law
from edc_bench.control.design import ControllerDesign
from edc_bench.errors import ConfigError
from edc_bench.perf.compute import lean_tick
from edc_bench.population.batch import run_batch
from edc_bench.population.valves import new_valves
from edc_bench.records.record import write_record
from edc_bench.replay import replay_record


@pytest.fixture(scope="module")
def short(variant: Variant) -> Variant:
    return with_changes(variant, {"excitation": {"duration_s": 8.0}}, "test: 8 s")


def _drives(variant: Variant) -> dict[str, np.ndarray]:
    """The drives of the loop, the batch path and the floor on the same short test."""
    loop = run_simulated_test(variant, "new", 1, classify=False, check_gains=False)
    batch = run_batch(variant, new_valves(variant, 2, 5), [5, 6])
    design = ControllerDesign.from_variant(variant)
    floor = lean_tick(design, 10.0)
    positions = np.asarray(loop.trace["position_mm"])
    floor_drives = np.array([floor(k, float(positions[max(k - 1, 0)])) for k in range(1000)])
    return {"loop": loop.trace["drive_v"], "batch": batch.parameters, "floor": floor_drives, "result": loop}


def _pid_bias(original):  # one PID detail: 20 mV more feedback
    def changed(*args: object, **kwargs: object) -> object:
        return original(*args, **kwargs) + 0.02
    return changed


def _regressors_swapped(original):  # one step of the tick's composition: the 2nd and 3rd derivatives trade places
    def changed(ops: object, w: object, r: object, r1: object, r2: object, r3: object) -> None:
        original(ops, w, r, r1, r3, r2)
    return changed


@pytest.mark.slow  # the default suite's 5 minutes; CI's slow pass runs it
@pytest.mark.parametrize(("name", "change"), [("pid_update", _pid_bias), ("regressors", _regressors_swapped)])
def test_one_detail_changed_in_one_place_changes_the_loop_replay_the_batch_and_the_floor(
        short: Variant, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, name: str, change) -> None:
    """#54: the PID's arithmetic, and the tick's composition (regressors, their split, the coil ratio, the
    estimator's target: law.feedforward_tick), are each written once: changed in one place, the loop, replay, the
    batch path and the floor all change, replay and the batch's tick to the bit."""
    before = _drives(short)
    folder = write_record(before["result"], tmp_path / "before", figure=False)
    monkeypatch.setattr(law, name, change(getattr(law, name)))
    after = _drives(short)
    for part in ("loop", "batch", "floor"):
        assert not np.array_equal(before[part], after[part]), part
    # the batch's tick follows to the bit: fed the changed loop's samples, it sends the changed loop's drives
    trace = {name: np.asarray(column) for name, column in after["result"].trace.items()}
    assert np.array_equal(batch_drives_from_loop(short, trace, 1), trace["drive_v"])
    # replay runs the same law: a record made under it replays to the bit, one made before does not
    changed = write_record(after["result"], tmp_path / "after", figure=False)
    assert replay_record(changed).reproduced
    with pytest.raises(ConfigError, match="replayed drives differ"):
        replay_record(folder)


def test_the_floats_and_the_arrays_compose_a_tick_alike(variant: Variant) -> None:
    """The loop's controller (floats) and the batch path (arrays) compose a tick from the same regressors to the
    same bits: the one composition, two backends."""
    design = ControllerDesign.from_variant(variant)
    c = design.composition()
    rng = np.random.default_rng(3)
    theta = rng.normal(size=(len(c.estimated), 4))
    mid = rng.normal(size=(4, 4)) * [[1e3], [1e2], [10.0], [1.0]]
    mid[2, 0] = 0.0  # sgn(0)
    rho, feedback, t_s = np.array([1.0, 1.1, 0.9, 1.05]), rng.normal(size=4), variant.excitation.move_s + 1.0
    w_arrays = np.empty((6, 4))
    law.regressors(law.ARRAYS, w_arrays, mid[3], mid[2], mid[1], mid[0])
    arrays = law.feedforward_tick(law.ARRAYS, c, theta, w_arrays, feedback, rho, t_s)
    for n in range(4):
        w = [0.0] * 6
        law.regressors(law.SCALAR, w, *(float(mid[row, n]) for row in (3, 2, 1, 0)))
        assert w == w_arrays[:, n].tolist()
        u1, u, saturated, learn, w_est, fixed_part = law.feedforward_tick(
            law.SCALAR, c, theta[:, n].tolist(), w, float(feedback[n]), float(rho[n]), t_s)
        assert (u1, u, saturated, bool(learn)) == (arrays[0][n], arrays[1][n], arrays[2][n], bool(arrays[3][n]))
        assert w_est == arrays[4][:, n].tolist() and fixed_part == np.broadcast_to(arrays[5], 4)[n]
        assert law.estimator_target(u, float(rho[n]), fixed_part) == \
            law.estimator_target(arrays[1], rho, arrays[5])[n]


def test_floats_and_arrays_give_the_same_pid(variant: Variant) -> None:
    """The two backends run one definition: the same errors give the same outputs, test by test."""
    design = ControllerDesign.from_variant(variant)
    c = law.PidCoefficients.of(design.pid_gains, design.period_s, design.drive_limit_v)
    rng = np.random.default_rng(3)
    errors = rng.normal(0.0, 0.5, (200, 3))
    saturated = rng.integers(-1, 2, (200, 3))
    usable = rng.random((200, 3)) > 0.2
    arrays = law.PidState(np.zeros(3))
    scalars = [law.PidState() for _ in range(3)]
    for k in range(200):
        out = law.pid_update(law.ARRAYS, c, arrays, errors[k], saturated[k], usable[k])
        for n in range(3):
            assert law.pid_update(law.SCALAR, c, scalars[n], float(errors[k, n]), int(saturated[k, n]),
                                  bool(usable[k, n])) == out[n]


def test_floats_and_arrays_give_the_same_estimates(variant: Variant) -> None:
    design = ControllerDesign.from_variant(variant)
    n = len(design.theta0)
    rng = np.random.default_rng(4)
    theta_a = np.tile(np.array(design.theta0)[:, None], (1, 2))
    P_a = np.tile(np.diag(np.array(design.prior_std) ** 2)[:, :, None], (1, 1, 2))
    theta_s = [list(design.theta0) for _ in range(2)]
    P_s = [[[s * s if i == j else 0.0 for j, s in enumerate(design.prior_std)] for i in range(n)] for _ in range(2)]
    for _ in range(300):
        w = rng.normal(0.0, 1.0, (n, 2))
        y = rng.normal(0.0, 1.0, 2)
        law.rls_update(law.ARRAYS, theta_a, P_a, w, y, 0.999, 1e6, np.array([True, True]))
        for v in range(2):
            law.rls_update(law.SCALAR, theta_s[v], P_s[v], w[:, v].tolist(), float(y[v]), 0.999, 1e6)
    for v in range(2):  # the primitives sum in one order, and keep P symmetric alike: the same bits
        assert theta_a[:, v].tolist() == theta_s[v]
        assert P_a[:, :, v].tolist() == P_s[v]
    # and a test alone gives what it gives among others (numpy's own reductions order terms by the arrays' shape)
    for n in (1, 3, 64, 301):
        w = rng.normal(0.0, 1.0, (6, n)) * 10.0 ** rng.uniform(-6, 3, (6, 1))
        m = rng.normal(0.0, 1.0, (6, 6, n)) * 10.0 ** rng.uniform(-6, 3, (6, 6, 1))
        dot, matvec = law.ARRAYS.dot(w, w), law.ARRAYS.matvec(m, w)
        for j in range(n):
            assert dot[j] == law.SCALAR.dot(w[:, j].tolist(), w[:, j].tolist())
            assert matvec[:, j].tolist() == law.SCALAR.matvec(m[:, :, j].tolist(), w[:, j].tolist())
