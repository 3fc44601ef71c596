"""`edc-bench test`: the JSON summary, the human output, bad input in one clear line, unstable gains refused."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest
from helpers import REPO, edc_bench


def test_cli_test_json_summary(tmp_path: Path) -> None:
    proc = edc_bench("test", "--valve", "faulty", "--seed", "3", "--duration-s", "15", "--json", "--out", "rec",
                     "--no-figure", cwd=tmp_path)
    assert proc.returncode == 11, proc.stderr  # FAIL
    summary = json.loads(proc.stdout)  # stdout is only JSON
    assert summary["verdict"] == "FAIL"
    assert summary["classification"]["probability_faulty"] > 0.5
    assert summary["classification"]["distance"] > 0.03
    assert {"af", "a1"} <= set(summary["features"])
    assert set(summary["parameters"]) == {"a3", "a2", "a1", "a0", "b", "af"}
    assert summary["converged"] is True
    assert set(summary["truth"]) == {"a3", "a2", "a1", "a0", "b", "af"}
    assert abs(summary["features"]["af"] / summary["truth"]["af"] - 1) < 0.08
    assert Path(tmp_path / summary["record_dir"], "record.json").is_file()
    assert set(summary["parameters"]["af"]) == {"value", "std", "estimated", "truth", "error_rel"}  # simulated


def test_the_json_summary_of_a_test_without_a_true_value_gives_none() -> None:
    """A rig on a bus has no true parameters: the summary's parameters have no truth keys (as the JSON always
    gave them), not truth: null."""
    import dataclasses

    from edc_bench.bench import run_simulated_test
    from edc_bench.cli.test_summary import TestSummary
    from edc_bench.config import load_variant, with_changes

    result = run_simulated_test(with_changes(load_variant(), {"excitation": {"duration_s": 8.0}}, "test"), "new", 1,
                                classify=False, check_gains=False)
    untrue = {name: p.model_copy(update={"truth": None, "error_rel": None}) for name, p in result.parameters.items()}
    result = dataclasses.replace(result, judgement=dataclasses.replace(result.judgement, parameters=untrue), truth=None)
    parameters = TestSummary.of(result, None).as_json()["parameters"]
    assert set(parameters) == {"a3", "a2", "a1", "a0", "b", "af"}
    assert all(set(entry) == {"value", "std", "estimated"} for entry in parameters.values()), parameters


def test_cli_human_output_shows_the_numbers(tmp_path: Path) -> None:
    proc = edc_bench("test", "--duration-s", "15", "--no-figure", "--out", "rec", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr  # PASS
    assert "verdict: PASS" in proc.stdout
    assert "P(faulty)" in proc.stdout
    assert "af = " in proc.stdout and "truth" in proc.stdout
    assert "s left" in proc.stderr  # progress (plain lines when not on a terminal)


@pytest.mark.parametrize(
    ("args", "message", "code"),
    [
        (["--variant", "nope"], "unknown variant 'nope'", 2),
        (["--valve", "cracked"], "unknown valve 'cracked'", 2),
        (["--duration-s", "3"], "excitation.duration_s (3 s) is too short", 2),
        (["--interface", "nosuchbus"], "--interface 'nosuchbus': python-can has no such interface; use one of", 2),
        (["--interface", "socketcan", "--channel", "nosuchcan0"], "cannot open the CAN bus (interface=socketcan", 3),
    ],
)
def test_cli_bad_input_is_one_clear_line(tmp_path: Path, args: list[str], message: str, code: int) -> None:
    proc = edc_bench("test", *args, cwd=tmp_path)
    assert proc.returncode == code
    assert message in proc.stderr
    assert "Traceback" not in proc.stderr


def test_cli_refuses_unstable_gains(tmp_path: Path) -> None:
    source = (REPO / "configs" / "p-edc-default.toml").read_text()
    bad = tmp_path / "hot.toml"
    hot = re.sub(r"kp_v_per_mm = [0-9.]+", "kp_v_per_mm = 3.0", source)
    bad.write_text(hot.replace('name = "p-edc-default"', 'name = "hot"'))
    proc = edc_bench("test", "--variant", str(bad), cwd=tmp_path)
    assert proc.returncode == 2
    assert "unstable" in proc.stderr and "Traceback" not in proc.stderr
