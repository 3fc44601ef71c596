"""Baselines: every shipped variant has one, bad files are refused, `edc-bench calibrate` measures one."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from helpers import edc_bench

from edc_bench.config import load_variant
from edc_bench.errors import ConfigError
from edc_bench.verdict.baseline import load_baseline, read_baseline


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
    proc = edc_bench("calibrate", "--tests", "8", "--seed", "5", "--baseline-file", str(out), cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    baseline = read_baseline(out, "p-edc-default")
    assert baseline.tests == 8 == len(baseline.test_list)
    assert all(t.uncertainty_known for t in baseline.test_list)  # each test's noise and misfit, for the interval
    assert (baseline.noise_rel(2.576) > 0).all()
    assert baseline.source == "simulated population" and baseline.software.startswith("edc-bench ")
    shipped = load_baseline(load_variant())
    assert baseline.af_v == pytest.approx(shipped.af_v, rel=0.1)
    assert baseline.a1_v_s_per_mm == pytest.approx(shipped.a1_v_s_per_mm, rel=0.1)


def test_shipped_baselines_list_their_tests_and_state_their_uncertainty() -> None:
    for name in ("p-edc-default", "p-edc-long"):
        baseline = load_baseline(load_variant(name))
        assert baseline.tests == len(baseline.test_list) == 20
        assert baseline.af_v == pytest.approx(sum(t.af_v for t in baseline.test_list) / 20, rel=1e-12)
        assert 0 < baseline.af_uncertainty_v < 0.03 * baseline.af_v
        assert baseline.a1_uncertainty_v_s_per_mm == pytest.approx(baseline.a1_sd_v_s_per_mm / 20 ** 0.5)
    for name in ("p-edc-default", "p-edc-long", "p-edc-hard"):
        baseline = load_baseline(load_variant(name))
        assert all(t.uncertainty_known for t in baseline.test_list), name
        assert (0 < baseline.noise_rel(2.576)).all() and (baseline.noise_rel(2.576) < 0.01).all(), name
        assert (np.abs(baseline.core_shift_rel()) < 0.02).all(), name


def test_a_station_baseline_comes_before_the_library_one_and_an_earlier_one_is_kept(tmp_path, monkeypatch) -> None:
    from edc_bench.verdict.baseline import BaselineTest, baseline_from_tests, station_baseline_path, write_baseline

    monkeypatch.setenv("EDC_BENCH_VARIANTS_DIR", str(tmp_path / "variants"))
    variant = load_variant("p-edc-default")
    shipped = load_baseline(variant)
    first = baseline_from_tests([BaselineTest(0.08, 0.004, "A", "rig"), BaselineTest(0.09, 0.005, "B", "rig")],
                                station="bench 2")
    path = station_baseline_path(variant.name)
    assert write_baseline(path, first.to_toml(variant.name)) is None
    own = load_baseline(variant)
    assert (own.af_v, own.a1_v_s_per_mm) == pytest.approx((0.085, 0.0045), rel=1e-12)
    assert (own.tests, own.station, own.source) == (2, "bench 2", "rig")
    assert load_baseline(variant, station=False).af_v == shipped.af_v  # training keeps the simulated one
    kept = write_baseline(path, baseline_from_tests([BaselineTest(0.07, 0.003, "C", "rig")]).to_toml(variant.name))
    assert kept is not None and kept.parent.name == "earlier"
    assert read_baseline(kept, variant.name).tests == 2 and load_baseline(variant).tests == 1
    assert math.isnan(load_baseline(variant).af_uncertainty_v)  # one test: no uncertainty to state


def test_baseline_file_with_a_broken_test_entry(tmp_path: Path) -> None:
    path = tmp_path / "b.toml"
    path.write_text('variant = "x"\naf_v = 0.1\na1_v_s_per_mm = 0.01\n[[test]]\naf_v = "?"\n')
    with pytest.raises(ConfigError, match="numbers in each \\[\\[test\\]\\]"):
        read_baseline(path)


def test_a_test_entry_that_is_not_a_positive_number_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "b.toml"
    path.write_text('variant = "x"\naf_v = 0.1\na1_v_s_per_mm = 0.01\n[[test]]\naf_v = nan\na1_v_s_per_mm = 0.01\n')
    with pytest.raises(ConfigError, match="and those of every \\[\\[test\\]\\], must be positive numbers"):
        read_baseline(path)


def test_the_baseline_s_own_uncertainty_is_its_tests_noise_of_the_mean_and_their_mean_core_shift(tmp_path) -> None:
    from edc_bench.verdict.baseline import BaselineTest, baseline_from_tests

    tests = [BaselineTest(0.07, 0.004, "A", "rig", af_se_rel=0.003, a1_se_rel=0.004, af_core_shift_rel=0.001,
                          a1_core_shift_rel=-0.006),
             BaselineTest(0.08, 0.004, "B", "rig", af_se_rel=0.004, a1_se_rel=0.003, af_core_shift_rel=-0.003,
                          a1_core_shift_rel=-0.002)]
    baseline = baseline_from_tests(tests)
    z = 2.576
    noise = np.full(2, z * 0.005 / 2)  # sqrt(3^2 + 4^2) = 5 per mille, over two tests
    np.testing.assert_allclose(baseline.noise_rel(z), noise, rtol=1e-12)
    np.testing.assert_allclose(baseline.core_shift_rel(), [-0.001, -0.004], rtol=1e-12)
    path = tmp_path / "b.toml"
    path.write_text(baseline.to_toml("p-edc-default"))
    again = read_baseline(path, "p-edc-default")
    assert again.test_list == baseline.test_list
    np.testing.assert_allclose(again.noise_rel(z), noise, rtol=1e-12)
    # a file from before the figures were kept allows nothing for itself, as the nominal baseline does
    older = baseline_from_tests([BaselineTest(0.07, 0.004, "A", "rig")])
    assert not older.noise_rel(z).any() and not older.core_shift_rel().any()


def test_a_test_entry_with_a_negative_standard_error_is_refused_with_what_to_do(tmp_path: Path) -> None:
    path = tmp_path / "b.toml"
    path.write_text('variant = "x"\naf_v = 0.1\na1_v_s_per_mm = 0.01\n[[test]]\naf_v = 0.1\na1_v_s_per_mm = 0.01\n'
                    'af_se_rel = -0.01\n')
    with pytest.raises(ConfigError, match=r"\[\[test\]\] 1: af_se_rel must be a number of at least 0, not -0.01; "
                                          "delete the line"):
        read_baseline(path)


def test_where_a_baselines_tests_ran_is_a_value_an_older_sentence_read_once() -> None:
    """#54: 'measured on a rig' was decided by splitting the baseline's sentence on ' and '."""
    from edc_bench.records.reader import typed_record, upgraded
    from edc_bench.verdict.baseline import Baseline, BaselineTest, baseline_from_tests
    from edc_bench.verdict.baseline_source import BaselineSource

    mixed = baseline_from_tests([BaselineTest(0.07, 0.004, "A", BaselineSource.RIG),
                                 BaselineTest(0.08, 0.004, "B", "simulated rig")])  # a file's word is read as a value
    assert mixed.sources == {BaselineSource.RIG, BaselineSource.SIMULATED_RIG} and mixed.measured_on_rig
    assert mixed.source == "rig and simulated rig"
    # a record's summary keeps the values; a summary without them (an older record, a file) is read from its sentence
    summary = mixed.summary().model_dump(mode="json")
    assert Baseline.from_summary(summary).sources == mixed.sources
    older = {key: value for key, value in summary.items() if key != "sources"}
    assert Baseline.from_summary(older).measured_on_rig
    assert not Baseline.from_summary({**older, "source": "simulated rig"}).measured_on_rig
    assert Baseline.from_summary({**older, "source": "the rigs of another shop"}).sources == {BaselineSource.UNKNOWN}
    assert Baseline.from_summary({**older, "tests": 0}).sources == {BaselineSource.NOMINAL}
    # the summary's values win over its words
    assert not Baseline.from_summary({**summary, "sources": ["simulated population"],
                                      "source": "rig"}).measured_on_rig
    # an older record's baseline is upgraded on read, once, in the reader
    record = typed_record(upgraded({"schema": 9, "verdict": "PASS", "baseline": {**older, "source": "rig"}}), "x")
    assert record.baseline is not None and record.baseline.sources == [BaselineSource.RIG]
    nominal = typed_record(upgraded({"schema": 9, "verdict": "PASS", "baseline": {**older, "tests": 0}}), "x")
    assert nominal.baseline is not None and nominal.baseline.sources == [BaselineSource.NOMINAL]


def test_calibrate_keeps_each_tests_pump_and_says_what_its_pumps_let_the_sensor_be_judged_to(tmp_path: Path) -> None:
    """#67: the bring-up measures the pumps' spread where it measures the baseline: each test names its pump
    (--pump-serial), and calibrate says how finely the sensor's linearity is judged with the pumps it has, and
    asks for more pumps; with three or more it prints their spread and warns where it is wider than the type's
    stated tolerance."""
    import dataclasses

    from edc_bench.cli.calibrate_cmd import pump_lines
    from edc_bench.verdict.baseline import BaselineSource, baseline_from_tests

    out = tmp_path / "baseline.toml"
    proc = edc_bench("calibrate", "--valve", "new", "--pump-serial", "PUMP-1", "--seed", "3", "--baseline-file",
                     str(out), "--out", str(tmp_path / "records"), cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    baseline = read_baseline(out, "p-edc-default")
    assert [t.pump_serial for t in baseline.test_list] == ["PUMP-1"] and baseline.pumps == 0  # a simulated rig
    variant = load_variant()
    rig = [dataclasses.replace(t, source=BaselineSource.RIG) for t in baseline.test_list]
    one = baseline_from_tests(rig)
    [line] = pump_lines(variant, one)
    assert "ran in 1 pump(s)" in line and "--pump-serial SERIAL" in line and "3 or more pumps" in line

    def pump(serial: str, b_scale: float) -> object:
        return dataclasses.replace(rig[0], pump_serial=serial, b_v=rig[0].b_v * b_scale)

    even = baseline_from_tests([pump("A", 1.0), pump("B", 1.01), pump("C", 0.99)])
    lines = pump_lines(variant, even)
    assert "ran in 3 pumps" in lines[0] and "preload term b 1.0%" in lines[0] and len(lines) == 1
    wide = baseline_from_tests([pump("A", 1.0), pump("B", 1.12), pump("C", 0.88)])
    assert any(line.startswith("warning: the pumps' preload spreads more") for line in pump_lines(variant, wide))
