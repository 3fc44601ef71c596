"""`edc-bench classify`: a recorded test judged again, and bad input refused in one line."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from helpers import edc_bench

from edc_bench.verdict.verdicts import Verdict


def test_classify_a_record_folder(tmp_path: Path) -> None:
    proc = edc_bench("test", "--valve", "worn", "--duration-s", "15", "--json", "--no-figure", "--out", "rec",
                     cwd=tmp_path)
    summary = json.loads(proc.stdout)
    again = edc_bench("classify", summary["record_dir"], "--json", cwd=tmp_path)
    assert again.returncode == 11, again.stderr
    out = json.loads(again.stdout)
    assert out["verdict"] == summary["verdict"] == Verdict.FAIL
    assert out["probability_faulty"] == pytest.approx(summary["classification"]["probability_faulty"])
    # the classification's fields at the top level, in the order the command has always printed them
    assert list(out)[:4] == ["variant", "features", "verdict", "probability_faulty"], list(out)


@pytest.mark.parametrize(("args", "message"), [
    (["--af", "0.05"], "give --af and --a1"),
    (["--af", "-1", "--a1", "0.01"], "argument --af: -1 is not above 0"),
    (["nowhere"], "no such record folder"),
    (["--af", "0.05", "--a1", "0.004", "--model", "missing.onnx"], "not found"),
])
def test_classify_bad_input(tmp_path: Path, args: list[str], message: str) -> None:
    proc = edc_bench("classify", *args, cwd=tmp_path)
    assert proc.returncode == 2 and message in proc.stderr and "Traceback" not in proc.stderr
