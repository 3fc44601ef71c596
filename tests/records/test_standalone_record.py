"""A record folder stands alone: the report draws from it on a machine without the variant or the model."""

from __future__ import annotations

import hashlib
import json
import shutil
import subprocess
import sys
from pathlib import Path

import can
import pytest

from edc_bench.bench import run_simulated_test
from edc_bench.config import load_variant
from edc_bench.physics.feedforward import nominal_parameters
from edc_bench.records.record import write_record
from edc_bench.records.report import REPORT_PNGS, draw_report
from edc_bench.verdict.classifier import packaged_model_path


@pytest.fixture(scope="module")
def worn_record(tmp_path_factory: pytest.TempPathFactory) -> Path:
    variant = load_variant("p-edc-default")
    result = run_simulated_test(variant, "worn", seed=4, valve_id="V-77")
    return write_record(result, tmp_path_factory.mktemp("records"), figure=False)


def test_record_names_the_model_and_holds_what_the_report_shows(worn_record: Path) -> None:
    record = json.loads((worn_record / "record.json").read_text())
    cls = record["classification"]
    assert cls["model_file"] == "valve_mlp.onnx"
    assert cls["model_sha256"] == hashlib.sha256(packaged_model_path().read_bytes()).hexdigest()
    refs = record["reference_values"]
    assert refs["af"] == {"value": record["baseline"]["af_v"], "source": "baseline"}
    assert refs["a0"] == {"value": nominal_parameters(load_variant("p-edc-default")).a0, "source": "nominal"}
    plane = record["decision_plane"]
    assert len(plane["p_faulty"]) == len(plane["p_faulty"][0]) == 60
    assert plane["threshold"] == cls["threshold"] and plane["marginal_band"] == cls["marginal_band"]
    assert record["identification"]["excitation_start_s"] == record["config"]["excitation"]["move_s"]


# Run in a fresh interpreter where the variant library, the physics, control, diagnosis and the model cannot
# be imported or found, as on another machine that only has the folder.
_ISOLATED_REPORT = """
import sys
for name in ("edc_bench.config", "edc_bench.physics", "edc_bench.control", "edc_bench.verdict.classifier",
             "edc_bench.verdict.judgement", "edc_bench.verdict.baseline", "onnxruntime", "edc_bench.sim"):
    sys.modules[name] = None  # any import of these now fails
from edc_bench.records.report import draw_report
draw_report(sys.argv[1])
"""


def test_report_on_a_copied_folder_without_variant_or_model_is_the_same(worn_record: Path, tmp_path: Path) -> None:
    _, pngs_here = draw_report(worn_record, tmp_path / "here")
    elsewhere = tmp_path / "other-machine" / worn_record.name
    shutil.copytree(worn_record, elsewhere)
    env_dirs = {"EDC_BENCH_DATA_DIR": str(tmp_path / "empty-data"), "EDC_BENCH_CACHE_DIR": str(tmp_path / "cache")}
    import os

    proc = subprocess.run([sys.executable, "-c", _ISOLATED_REPORT, str(elsewhere)], capture_output=True, text=True,
                          cwd=tmp_path, env={**os.environ, **env_dirs}, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert [png.name for png in pngs_here] == list(REPORT_PNGS)
    for png in pngs_here:
        assert (elsewhere / png.name).read_bytes() == png.read_bytes()


def test_can_log_is_python_cans_format_with_absolute_times_and_directions(worn_record: Path) -> None:
    record = json.loads((worn_record / "record.json").read_text())
    messages = list(can.LogReader(str(worn_record / "can.log")))
    origin = record["loop"]["clock_origin_unix_s"]
    assert origin > 1.7e9  # a real date, not 1970
    assert messages[0].timestamp >= origin
    assert {m.is_rx for m in messages} == {True, False}
    sent = [m for m in messages if not m.is_rx]
    assert all(m.arbitration_id == 0x120 for m in sent)  # the bench sends only BENCH_CMD
    assert all(b.timestamp >= a.timestamp for a, b in zip(messages, messages[1:], strict=False))
