"""The benchmark runs and its floors do the same work; no test asserts a timing."""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from edc_bench.config import Variant
from edc_bench.control.design import ControllerDesign
from edc_bench.perf.compute import lean_tick, struct_floor
from edc_bench.perf.loops import stolen_mask, with_timing
from edc_bench.perf.suite import GROUPS
from edc_bench.protocol import Icd, Mode


@pytest.mark.slow  # the benchmark itself, about 30 s
def test_perf_quick_prints_every_group_and_leaves_the_history_alone(tmp_path: Path) -> None:
    station = tmp_path / "station"
    env = {**os.environ, "EDC_BENCH_DATA_DIR": str(station)}
    env.pop("EDC_BENCH_HISTORY_URL", None)
    # run from outside the checkout: `python -m` puts the working folder first on sys.path, and from the checkout's
    # root it would time the source tree, not the package this process imports (CI installs the package)
    proc = subprocess.run([sys.executable, "-m", "edc_bench", "perf", "--quick", "--json"],
                          capture_output=True, text=True, timeout=600, env=env, cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    # its simulated tests (the first-tick runs of `edc-bench test`) went to a scratch history, not the station's
    assert not (station / "history.sqlite").exists()
    report = json.loads(proc.stdout)
    figures = report["figures"]
    assert {f["group"] for f in figures} == set(GROUPS)
    names = " | ".join(f["name"] for f in figures)
    for expected in ("rls", "gradient", "BENCH_CMD encode", "RIG_FEEDBACK decode", "simulated full-length test of 30 s",
                     "simulated early-stopped (the technician's) test",
                     "1 kHz", "2 kHz", "batch path", "--help", "first tick", "safe stop to its decision on screen"):
        assert expected in names
    for f in figures:
        assert f["value"] is not None and math.isfinite(f["value"]) and f["value"] >= 0, f
        assert f["met"] is None, f
        if f["group"] == "simulated":  # a figure without a target (#54 retired it)
            assert not f["target"] and "target not judged" not in f["note"], f
        else:  # a quick run's figures are too short to be judged against their target, and say so
            assert f["target"] and "target not judged: a quick run is too short" in f["note"], f
    assert report["environment"]["quick"] is True


def _floor_and_loop_drives(variant: Variant) -> tuple[list[float], list[float], int]:
    """The loop's controller and the floor on the same 6000 samples (no coil current: both keep the coil's prior)."""
    design = ControllerDesign.from_variant(variant)
    ctl, floor = design.controller(1.0), lean_tick(design, 1.0)
    rng = np.random.default_rng(0)
    x, loop, lean = 1.0, [], []
    for k in range(6000):  # past the move, so the estimator adapts
        loop.append(ctl.step(k, x))
        lean.append(floor(k, x))
        x = ctl.reference_mm + rng.normal(0.0, 0.005)
    return loop, lean, ctl.estimator.updates


@pytest.mark.parametrize("kind", ["rls", "gradient"])
def test_tick_floor_does_the_controllers_arithmetic_to_the_bit(variant: Variant, kind: str,
                                                               monkeypatch: pytest.MonkeyPatch) -> None:
    """#54: the floor is the loop's tick composition, not a copy of it: the same drives to the bit, and after one
    step of the composition is changed in one place (the regressors' 2nd and 3rd derivatives swapped), the same
    changed drives to the bit."""
    from edc_bench.control import law

    variant = variant.model_copy(update={"estimator": variant.estimator.model_copy(update={"kind": kind})})
    loop, lean, updates = _floor_and_loop_drives(variant)
    assert lean == loop and updates > 1000
    original = law.regressors
    monkeypatch.setattr(law, "regressors", lambda ops, w, r, r1, r2, r3: original(ops, w, r, r1, r3, r2))
    changed_loop, changed_lean, _ = _floor_and_loop_drives(variant)
    assert changed_lean == changed_loop and changed_loop != loop


def test_struct_floor_encodes_and_decodes_like_the_codec(icd: Icd) -> None:
    encode, decode = struct_floor(icd)
    for counter, mode, drive, ref in ((0, Mode.SAFE, 0.0, 0.0), (255, Mode.RUN, -32.768, 65.535), (9, 1, 1.2345, 7.5)):
        assert encode(counter, mode, drive, ref) == icd.make_bench_cmd(counter, mode, drive, ref)
    payload = icd.make_rig_feedback(3, amp_enabled=True, watchdog_tripped=False, over_current=True, lvdt_fault=False,
                                    travel_limit=True, position_mm=12.345, current_a=-0.5)
    assert [float(v) for v in decode(payload)] == pytest.approx([float(v) for v in icd.parse_rig_feedback(payload)])


def test_steal_windows_mark_neighbouring_ticks() -> None:
    # samples every 20 ms; 5 ms of steal between the samples at 40 and 60 ms
    steal = np.array([(0.0, 1.0), (20e6, 1.0), (40e6, 1.0), (60e6, 1.005), (80e6, 1.005), (100e6, 1.005),
                      (120e6, 1.005)])
    times = np.array([5e6, 30e6, 50e6, 70e6, 110e6])
    assert stolen_mask(times, steal).tolist() == [False, True, True, True, False]
    assert not stolen_mask(times, steal[:1]).any()


def test_short_benchmark_variant_shrinks_the_convergence_window(variant: Variant) -> None:
    short = with_timing(variant, period_s=0.0005, duration_s=3.0)
    assert short.controller.period_s == 0.0005
    assert short.excitation.duration_s == 3.0
    assert short.acceptance.convergence_window_s < 1.0
    assert with_timing(variant).acceptance.convergence_window_s == variant.acceptance.convergence_window_s
