"""The coil is not the valve (issue #17): coils across their spec, warm coils, and a coil out of spec."""

from __future__ import annotations

import json

import numpy as np
import pytest
from helpers import edc_bench

from edc_bench.bench import run_simulated_test
from edc_bench.config import load_variant, with_changes
from edc_bench.errors import ConfigError
from edc_bench.physics.valve import parse_valve_spec
from edc_bench.verdict.verdicts import Verdict

#: The coils of the issue's table: the spec's ends and the paper's 0.7 ohm, and a coil warm from earlier tests.
COILS = ("coil_ohm=0.6", "coil_ohm=0.7", "coil_ohm=0.9", "coil_ohm=0.7,coil_temp_c=80")
# the issue's table: the low end and the warm coil in CI's slow pass (the default suite stays under 5 minutes)
TABLE_COILS = (pytest.param(COILS[0], marks=pytest.mark.slow), COILS[1], COILS[2],
               pytest.param(COILS[3], marks=pytest.mark.slow))


@pytest.fixture(scope="module")
def variant():
    return load_variant("p-edc-default")


@pytest.fixture(scope="module")
def new_valve_on_each_coil(variant):
    return {coil: run_simulated_test(variant, f"new,{coil}", seed=3, full_length=True,
                                     coil_temp_c=80.0 if "coil_temp_c=80" in coil else None) for coil in COILS}


@pytest.mark.slow  # seconds: CI's slow pass runs it (the default suite stays under 5 minutes on CI)
def test_features_of_one_valve_move_less_than_2_percent_across_the_coil_range(new_valve_on_each_coil) -> None:
    af = np.array([r.features.af for r in new_valve_on_each_coil.values()])
    a1 = np.array([r.features.a1 for r in new_valve_on_each_coil.values()])
    volt_af = np.array([r.judgement.features_volt.af for r in new_valve_on_each_coil.values()])
    print("af", af, "a1", a1, "af in volts", volt_af)
    assert np.ptp(af) / af.mean() < 0.02 and np.ptp(a1) / a1.mean() < 0.02
    # the volt features the paper used move with the coil (0.6 to 0.9 ohm, the 80 degC coil 1.23 x 0.7): ~50 %
    assert np.ptp(volt_af) / volt_af.mean() > 0.3


@pytest.mark.slow  # seconds: CI's slow pass runs it (the default suite stays under 5 minutes on CI)
def test_the_measured_resistance_is_within_1_percent_of_the_coil(new_valve_on_each_coil) -> None:
    for coil, result in new_valve_on_each_coil.items():
        truth = result.simulation.coil
        measured = result.judgement.coil
        print(coil, measured.resistance_20c_ohm, truth.resistance_20c_ohm, measured.resistance_ohm,
              truth.resistance_end_ohm, measured.warming_k, truth.temp_end_c - truth.temp_start_c)
        assert measured.resistance_20c_ohm == pytest.approx(truth.resistance_20c_ohm, rel=0.01)
        assert measured.resistance_ohm == pytest.approx(truth.resistance_end_ohm, rel=0.01)
        assert measured.in_spec is True
        assert result.verdict == Verdict.PASS, result.reasons
    # the coil warms in the test (a rested 0.9 ohm coil: about 10 K in 30 s) and the bench sees it
    assert new_valve_on_each_coil["coil_ohm=0.9"].judgement.coil.warming_k > 5.0


def test_a_1_1_ohm_coil_is_out_of_spec_and_fails(variant, tmp_path) -> None:
    result = run_simulated_test(variant, "new,coil_ohm=1.1", seed=3)
    assert result.judgement.coil.resistance_20c_ohm == pytest.approx(1.1, rel=0.01)
    assert result.judgement.coil.in_spec is False
    assert result.verdict == Verdict.FAIL
    assert result.reasons[0].startswith("coil out of spec: 1.") and "spec 0.6-0.9 ohm" in result.reasons[0]
    assert "the valve itself: PASS" in result.reasons[1]  # the valve is fine; the coil is the finding
    # the command line says it too, with the exit code of a FAIL
    proc = edc_bench("test", "--valve", "new,coil_ohm=1.1", "--json", "--no-figure", "--no-history", "--out", "rec",
                     cwd=tmp_path)
    assert proc.returncode == 11, proc.stderr
    summary = json.loads(proc.stdout)
    assert summary["verdict"] == "FAIL" and summary["coil"]["in_spec"] is False
    record = json.loads((tmp_path / summary["record_dir"] / "record.json").read_text())
    assert record["coil"]["in_spec"] is False and record["features_volt"]["af"] > record["features"]["af"]


def test_a_warm_coil_reads_high_unless_its_temperature_is_given(variant) -> None:
    """0.9 ohm at 20 degC, 60 degC at the start: assumed at 20 degC it reads 1.04 ohm, out of spec, and the
    reason says to give the temperature; given, it is in spec."""
    assumed = run_simulated_test(variant, "new,coil_ohm=0.9,coil_temp_c=60", seed=3)
    given = run_simulated_test(variant, "new,coil_ohm=0.9,coil_temp_c=60", seed=3, coil_temp_c=60.0)
    assert assumed.verdict == Verdict.FAIL and "--coil-temp-c" in assumed.reasons[0]
    assert given.verdict == Verdict.PASS and given.judgement.coil.resistance_20c_ohm == pytest.approx(0.9, rel=0.01)
    assert given.features == assumed.features  # the valve's figures do not depend on what was said of the coil


@pytest.mark.parametrize("coil", TABLE_COILS)
def test_the_issues_table_gives_pass_pass_fail_for_every_coil(variant, coil: str) -> None:
    """New valve PASS, clearance 0.16 mm (reusable) PASS, 0.19 mm (worn) FAIL or MARGINAL, whatever the coil."""
    temp = 80.0 if "coil_temp_c=80" in coil else None
    verdicts = [run_simulated_test(variant, f"{valve},{coil}", seed=0, coil_temp_c=temp).verdict
                for valve in ("new", "clearance=0.16", "clearance=0.19")]
    assert verdicts[0] == Verdict.PASS and verdicts[1] == Verdict.PASS, verdicts
    assert verdicts[2] in (Verdict.FAIL, Verdict.MARGINAL), verdicts


def test_valve_spec_takes_the_coil(variant) -> None:
    spec = parse_valve_spec("worn,coil_ohm=0.85,coil_temp_c=45", variant)
    assert spec.coil_ohm == 0.85 and spec.coil_temp_c == 45.0
    for bad in ("new,coil_ohm=-1", "new,coil_ohm=500", "new,coil_temp_c=900", "new,coil_temp_c=warm"):
        with pytest.raises(ConfigError, match="coil"):
            parse_valve_spec(bad, variant)


def test_a_coil_spec_that_leaves_out_the_nominal_coil_is_refused(variant) -> None:
    with pytest.raises(ConfigError, match="coil spec"):
        with_changes(variant, {"coil": {"resistance_max_ohm": 0.65}}, "test")


def test_coil_temp_c_on_the_command_line_is_checked(tmp_path) -> None:
    proc = edc_bench("test", "--coil-temp-c", "900", "--no-history", cwd=tmp_path)
    assert proc.returncode == 2 and "plausible coil temperature" in proc.stderr and "Traceback" not in proc.stderr


@pytest.mark.slow
def test_population_verdicts_do_not_depend_on_the_coil(variant) -> None:
    """300 valves with coils over 0.6-0.9 ohm starting at 20-80 degC, against the same valves with the nominal
    coil at 20 degC (batch path, same noise): the verdicts agree for at least 99 % of the valves outside the
    marginal band, and the features of each valve move little."""
    from edc_bench.experiments.studies import coil_population_study
    from edc_bench.verdict.classifier import ValveClassifier, packaged_model_path

    study = coil_population_study(variant, ValveClassifier(packaged_model_path()), 300, seed=17)
    ohms, temps, ok = study.coil_ohm, study.coil_temp_c, study.converged
    assert ohms.min() < 0.62 and ohms.max() > 0.88 and temps.min() < 23 and temps.max() > 77
    outside, same = study.outside_band, study.same_verdict
    agree = same[outside].sum() / max(outside.sum(), 1)
    d_af, d_a1, r_err = study.af_change_rel, study.a1_change_rel, study.coil_error_rel
    print(f"{ok.sum()} of 300 converged both ways; {outside.sum()} outside the marginal band; verdicts agree for "
          f"{agree:.2%} of those ({same.sum()} of {len(same)} in all); af moved {np.mean(d_af):+.3%} mean, "
          f"{np.max(np.abs(d_af)):.2%} max; a1 {np.mean(d_a1):+.3%} mean, {np.max(np.abs(d_a1)):.2%} max; "
          f"coil measured vs simulated at the end {np.mean(r_err):+.3%} mean, {np.max(np.abs(r_err)):.2%} worst")
    assert ok.sum() >= 290
    assert agree >= 0.99
    assert np.max(np.abs(d_af)) < 0.02 and np.max(np.abs(d_a1)) < 0.02
    assert np.max(np.abs(r_err)) < 0.01


@pytest.mark.parametrize(("spec", "words"), [
    ({"resistance_max_ohm": None}, ">= 0.6 ohm"), ({"resistance_min_ohm": None}, "<= 0.9 ohm"),
    ({"resistance_min_ohm": 0.6, "resistance_max_ohm": 0.9}, "0.6-0.9 ohm")])
def test_the_coil_line_says_a_one_sided_spec(variant, spec: dict, words: str) -> None:
    """A variant may give one side of the coil's spec: the technician's line says that side (it raised before)."""
    from edc_bench.config import with_changes
    from edc_bench.identification.coil_check import coil_line
    from edc_bench.identification.sections import CoilFinding

    low, high = spec.get("resistance_min_ohm", 0.6), spec.get("resistance_max_ohm", 0.9)
    finding = CoilFinding(resistance_ohm=0.75, resistance_start_ohm=0.72, resistance_20c_ohm=0.72, temp_start_c=20.0,
                          warming_k=1.2, spec_ohm=(low, high), in_spec=True)
    line = coil_line(finding)
    assert f"spec {words}: in spec" in line, line
    assert with_changes(variant, {"coil": spec}, "test").coil is not None  # the variant takes such a spec
