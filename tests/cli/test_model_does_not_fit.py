"""What a technician sees on a pump the model does not fit (#11): the command's JSON, and the report: page 1 says
a longer test will not help and what to check, page 2 gives every problem whole."""

from __future__ import annotations

import json
import os
from pathlib import Path

from helpers import REPO, edc_bench

from edc_bench.cli.exit_codes import ExitCode


def test_a_pump_the_model_does_not_fit_says_so_in_json_and_report(tmp_path: Path) -> None:
    from edc_bench.records.reader import load_record, load_trace
    from edc_bench.records.report import report_pages

    source = (REPO / "configs" / "p-edc-hard.toml").read_text(encoding="utf-8")
    changed = source.replace("force_constant_variation_per_mm = 0.022", "force_constant_variation_per_mm = 0.0667")
    changed = changed.replace('name = "p-edc-hard"', 'name = "p-edc-unfit"')
    assert changed.count("0.0667") == 1 and "p-edc-unfit" in changed
    (tmp_path / "unfit.toml").write_text(changed, encoding="utf-8")
    env = {"EDC_BENCH_HISTORY_URL": f"sqlite:///{tmp_path / 'h.sqlite'}"}
    done = edc_bench("test", "--variant", "unfit.toml", "--valve", "worn", "--nominal-baseline", "--no-figure",
                     "--out", "rec", "--json", cwd=tmp_path, env={**os.environ, **env})
    assert done.returncode == ExitCode.INVALID, done.stderr
    out = json.loads(done.stdout)
    assert out["verdict"] == "INVALID" and out["reasons"][0].startswith("the feedforward model does not fit")
    assert out["model_fit"]["fits"] is False and out["model_fit"]["problems"]
    assert out["stop"]["reason"] == "model does not fit" and out["stop"]["time_s"] < 30.0

    folder = Path(out["record_dir"]) if Path(out["record_dir"]).is_absolute() else tmp_path / out["record_dir"]
    record = load_record(folder)
    customer, engineer = (" ".join(t.get_text() for t in page.figure.texts)
                          for page in report_pages(record, load_trace(folder), folder.name))
    # the customer reads what it means for the valve; the engineer's page says what to check (#53: no engineer's
    # words on the customer's page)
    assert "it may be sticking or badly worn" in " ".join(customer.split())
    assert "needs its own variant" not in customer
    assert "The model does not fit this pump: a longer test will not help." in " ".join(engineer.split())
    assert "needs its own variant" in " ".join(engineer.split())
    assert record.identification is not None and record.identification.model_fit is not None
    for problem in record.identification.model_fit.problems:
        assert " ".join(problem.split()) in " ".join(engineer.split()), problem  # whole, wrapped
