"""Baselines: every shipped variant has one, bad files are refused, `edc-bench calibrate` measures one."""

from __future__ import annotations

from pathlib import Path

import pytest
from helpers import edc_bench

from edc_bench.config import load_variant
from edc_bench.diagnosis.baseline import load_baseline, read_baseline
from edc_bench.errors import ConfigError


@pytest.mark.parametrize("name", ["p-edc-default", "p-edc-long", "paper"])
def test_every_shipped_variant_has_a_calibrated_baseline(name: str) -> None:
    baseline = load_baseline(load_variant(name))
    assert baseline.calibrated and baseline.af_v > 0 and baseline.a1_v_s_per_mm > 0
    assert baseline.relative(baseline.af_v, baseline.a1_v_s_per_mm) == (1.0, 1.0)


def test_paper_baseline_is_valve_v1() -> None:
    baseline = load_baseline(load_variant("paper"))
    assert (baseline.af_v, baseline.a1_v_s_per_mm) == (0.0469, 0.0118)


def test_bad_baseline_file(tmp_path: Path) -> None:
    path = tmp_path / "b.toml"
    path.write_text('variant = "x"\naf_v = "lots"\n')
    with pytest.raises(ConfigError, match="needs af_v and a1_v_s_per_mm as numbers"):
        read_baseline(path)
    with pytest.raises(ConfigError, match="baseline is for variant 'x', not 'y'"):
        read_baseline(path, "y")


@pytest.mark.slow  # a population run (8 simulated tests), rarely touched
def test_calibrate_command_writes_a_baseline_near_the_nominal_one(tmp_path: Path) -> None:
    out = tmp_path / "baseline.toml"
    proc = edc_bench("calibrate", "--tests", "8", "--seed", "5", "--out", str(out), cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    baseline = read_baseline(out, "p-edc-default")
    assert baseline.tests == 8
    shipped = load_baseline(load_variant())
    assert baseline.af_v == pytest.approx(shipped.af_v, rel=0.1)
    assert baseline.a1_v_s_per_mm == pytest.approx(shipped.a1_v_s_per_mm, rel=0.1)
