"""Calibration as a workflow: no verdict on an uncalibrated variant, --append valve by valve, reasons for INVALID."""

from __future__ import annotations

import json
import os
import tomllib
from pathlib import Path

import pytest
from helpers import REPO, edc_bench

from edc_bench.cli.exit_codes import ExitCode
from edc_bench.records.reader import load_record


def _station(tmp_path: Path, name: str = "p-edc-uncal", extra: str = "", duration_s: float = 30.0) -> dict[str, str]:
    """A station whose variant folder holds a copy of the default variant under a name with no baseline."""
    folder = tmp_path / "variants"
    folder.mkdir(exist_ok=True)
    text = (REPO / "configs" / "p-edc-default.toml").read_text(encoding="utf-8")
    text = text.replace("duration_s = 30.0", f"duration_s = {duration_s!r}")
    text = text.replace('name = "p-edc-default"', f'name = "{name}"').replace("PE-EDC-0001", f"PE-{name}")
    (folder / f"{name}.toml").write_text(text + extra, encoding="utf-8")
    return {**os.environ, "EDC_BENCH_VARIANTS_DIR": str(folder)}


@pytest.mark.slow  # over 5 s each: the default suite's 5 minutes (CI's slow pass runs it)
def test_a_test_on_an_uncalibrated_variant_is_invalid_with_the_calibrate_command(tmp_path) -> None:
    env = _station(tmp_path)
    common = ("test", "--variant", "p-edc-uncal", "--duration-s", "15", "--no-history", "--no-figure",
              "--out", str(tmp_path / "records"))
    refused = edc_bench(*common, "--json", cwd=tmp_path, env=env)
    assert refused.returncode == ExitCode.INVALID, refused.stderr
    out = json.loads(refused.stdout)
    assert out["verdict"] == "INVALID" and out["converged"] is True  # the test itself was good
    assert out["reasons"][0].startswith("variant not calibrated: p-edc-uncal has no measured new-valve baseline")
    assert "'edc-bench calibrate --variant p-edc-uncal --valve new --append'" in out["reasons"][0]
    assert out["classification"] is None

    judged = edc_bench(*common, "--plain", "--nominal-baseline", cwd=tmp_path, env=env)
    assert judged.returncode == ExitCode.OK, judged.stderr  # a new valve, judged against its nominal figures
    assert "judged against the NOMINAL baseline (--nominal-baseline)" in judged.stdout
    assert "baseline: NOMINAL baseline: the variant is not calibrated" in judged.stdout
    record_dir = Path(judged.stdout.split("record: ")[1].splitlines()[0])
    if not record_dir.is_absolute():
        record_dir = tmp_path / record_dir
    record = load_record(record_dir)
    assert record.baseline is not None and record.baseline.calibrated is False
    assert record.reference_values["af"].source == "NOMINAL baseline (not calibrated)"
    replayed = edc_bench("replay", str(record_dir), cwd=tmp_path, env=env)  # judged again the same way
    assert replayed.returncode == ExitCode.OK, replayed.stdout + replayed.stderr
    from edc_bench.records.reader import load_trace
    from edc_bench.records.report import report_pages

    from matplotlib.text import Text

    customer, engineer = (" ".join(" ".join(t.get_text() for t in page.figure.findobj(Text)).split())
                          for page in report_pages(record, load_trace(record_dir), record_dir.name))
    assert ("Compared with the pump type's data-sheet figures, not with measured new valves: this verdict may be "
            "wrong until the pump type is calibrated (edc-bench calibrate --append).") in customer
    assert "NOMINAL baseline: the variant is not calibrated, af and a1 were compared with figures" in engineer
    assert "new valve (data sheet)" in customer  # the decision plot's legend names what (1, 1) is


@pytest.mark.slow  # 10-16 s: the default suite stays under 5 minutes; CI's slow pass runs it
def test_calibrate_append_valve_by_valve_keeps_every_test_and_its_record(tmp_path) -> None:
    env = _station(tmp_path, duration_s=15.0)
    base = ("calibrate", "--variant", "p-edc-uncal", "--valve", "new", "--append", "--station", "bench 7",
            "--out", str(tmp_path / "records"))
    first = edc_bench(*base, "--valve-id", "N-1", cwd=tmp_path, env=env)
    assert first.returncode == 0, first.stderr
    assert "1 test(s) so far" in first.stderr
    assert "run: edc-bench calibrate --variant p-edc-uncal --valve new --append --station 'bench 7'" in first.stderr
    assert "--valve-id" not in first.stderr.split("run: ")[1]  # the next valve has its own id
    second = edc_bench(*base, "--valve-id", "N-2", cwd=tmp_path, env=env)
    assert second.returncode == 0, second.stderr
    path = tmp_path / "variants" / "baselines" / "p-edc-uncal.toml"
    data = tomllib.loads(path.read_text(encoding="utf-8"))
    assert data["tests"] == 2 and [t["valve_id"] for t in data["test"]] == ["N-1", "N-2"]
    assert data["source"] == "simulated rig" and data["station"] == "bench 7"
    assert data["software"].startswith("edc-bench ") and data["written_at"].startswith("20")
    assert "af_uncertainty_v" in data and "a1_uncertainty_v_s_per_mm" in data
    assert data["test"][0]["af_v"] != data["test"][1]["af_v"]  # fresh noise for the second run
    for test in data["test"]:
        assert (Path(test["record"]) / "record.json").is_file()
        assert test["record"] in second.stderr  # listed as the records behind it
    assert len(list((path.parent / "earlier").glob("p-edc-uncal-*.toml"))) == 1  # the one-test file, kept

    after = edc_bench("test", "--variant", "p-edc-uncal", "--no-history", "--no-figure",
                      "--json", "--out", str(tmp_path / "records"), cwd=tmp_path, env=env)
    assert after.returncode == ExitCode.OK, after.stderr  # calibrated now: judged
    judged = json.loads(after.stdout)
    assert judged["verdict"] == "PASS"
    assert any(r.startswith("caution: the baseline rests on 2 new-valve test(s)") for r in judged["reasons"])
    more = edc_bench(*base, "--valve-id", "N-3", cwd=tmp_path, env=env)  # the baseline changes again
    assert more.returncode == 0, more.stderr
    replayed = edc_bench("replay", judged["record_dir"], cwd=tmp_path, env=env)  # against the record's baseline
    assert replayed.returncode == ExitCode.OK, replayed.stdout + replayed.stderr


@pytest.mark.slow  # seconds: CI's slow pass runs it (the default suite stays under 5 minutes on CI)
def test_every_invalid_calibration_test_shows_its_reason(tmp_path) -> None:
    # a limit no test can meet: every test is INVALID, poorly conditioned
    env = _station(tmp_path, "p-edc-strict", "\n[acceptance]\nmax_condition_number = 2.0\n", duration_s=12.0)
    result = edc_bench("calibrate", "--variant", "p-edc-strict", "--valve", "new", "--append", "--tests", "2",
                       "--out", str(tmp_path / "records"), cwd=tmp_path, env=env)
    assert result.returncode == ExitCode.INVALID, result.stderr
    assert result.stderr.count("INVALID, not used: ") == 2
    assert result.stderr.count("poorly conditioned regression: condition number") == 2
    assert "no converged new-valve test, so no baseline" in result.stderr
    assert not (tmp_path / "variants" / "baselines" / "p-edc-strict.toml").exists()
    assert "Traceback" not in result.stderr
    # a baseline already there stays as it was when a run adds nothing
    folder = tmp_path / "variants" / "baselines"
    folder.mkdir(exist_ok=True)
    kept = 'variant = "p-edc-strict"\naf_v = 0.07\na1_v_s_per_mm = 0.004\ntests = 1\n' \
           '[[test]]\naf_v = 0.07\na1_v_s_per_mm = 0.004\n'
    (folder / "p-edc-strict.toml").write_text(kept)
    again = edc_bench("calibrate", "--variant", "p-edc-strict", "--valve", "new", "--append",
                      "--out", str(tmp_path / "records"), cwd=tmp_path, env=env)
    assert again.returncode == ExitCode.INVALID and "is unchanged" in again.stderr
    assert (folder / "p-edc-strict.toml").read_text() == kept and not (folder / "earlier").exists()


def test_bad_calibrate_arguments_are_refused_before_any_test(tmp_path) -> None:
    env = _station(tmp_path)
    for args, message in (
        (("--out", "b.toml"), "--out is the folder for the tests' records"),
        (("--tests", "0"), "argument --tests: 0 is not a count: give 1 or more"),
        (("--valve", "new", "--interface", "virtual"), "--valve simulates a valve on the simulated rig"),
        (("--baseline-file", str(tmp_path)), "is a folder; give a file such as"),
        (("--write", "--append"), "not allowed with argument"),
        (("--valve", "worn", "--write"), "--valve worn: not a new valve"),
        (("--valve", "new", "--out", str(REPO / "README.md")), "is a file, not a folder"),
        (("--valve", "new", "--baseline-file", str(tmp_path / "variants" / "p-edc-uncal.toml")),
         "the file there is not a baseline (is it the variant file?)"),
        (("--baseline-file", "/proc/no/such/b.toml"), "cannot make its folder"),
    ):
        result = edc_bench("calibrate", "--variant", "p-edc-uncal", *args, cwd=tmp_path, env=env)
        assert result.returncode == ExitCode.BAD_INPUT and message in result.stderr, (args, result.stderr)
    shipped = tmp_path / "variants" / "baselines"
    shipped.mkdir(exist_ok=True)
    (shipped / "p-edc-uncal.toml").write_text('variant = "p-edc-uncal"\naf_v = 0.07\na1_v_s_per_mm = 0.004\ntests = 3\n')
    old = edc_bench("calibrate", "--variant", "p-edc-uncal", "--valve", "new", "--append", cwd=tmp_path, env=env)
    assert old.returncode == ExitCode.BAD_INPUT and "does not list its tests" in old.stderr


def test_classify_does_not_judge_an_uncalibrated_variant_silently(tmp_path) -> None:
    env = _station(tmp_path)
    values = ("classify", "--variant", "p-edc-uncal", "--af", "0.071", "--a1", "0.0038")
    refused = edc_bench(*values, cwd=tmp_path, env=env)
    assert refused.returncode == ExitCode.INVALID and "variant not calibrated" in refused.stdout
    judged = edc_bench(*values, "--nominal-baseline", "--json", cwd=tmp_path, env=env)
    out = json.loads(judged.stdout)
    assert out["baseline"]["calibrated"] is False and out["reasons"][0].startswith("judged against the NOMINAL")
    assert judged.returncode in (ExitCode.OK, ExitCode.MARGINAL, ExitCode.FAIL)
