"""The record folder: record.json, the columnar trace, the CAN log python-can reads back."""

from __future__ import annotations

import json
from pathlib import Path

import can
import numpy as np
import pytest

from edc_bench.bench import run_simulated_test
from edc_bench.config import load_variant, parse_variant
from edc_bench.protocol import BENCH_CMD_ID, RIG_FEEDBACK_ID
from edc_bench.records.record import write_record
from edc_bench.runtime.trace import TRACE_COLUMNS


@pytest.fixture(scope="module")
def record(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, object]:
    data = load_variant().model_dump()
    data["excitation"]["duration_s"] = 12.0
    result = run_simulated_test(parse_variant(data), "worn", 2, valve_id="V/0042 test", check_gains=False)
    return write_record(result, tmp_path_factory.mktemp("records")), result


def test_record_folder_is_complete(record) -> None:
    folder, result = record
    assert sorted(p.name for p in folder.iterdir()) == ["can.log", "record.json", "report.png", "trace.npz"]
    doc = json.loads((folder / "record.json").read_text())
    for key in ("verdict", "reasons", "valve_id", "variant", "software_version", "firmware_version", "features",
                "parameters", "converged", "identification", "timing", "loop", "config", "truth", "files"):
        assert key in doc, key
    assert doc["valve_id"] == "V/0042 test"
    assert doc["firmware_version"] == "1.0"
    assert doc["config"]["pump"]["name"] == "p-edc-default"
    assert doc["parameters"]["af"]["std"] > 0
    assert doc["timing"]["ticks"] == 12_000
    assert doc["files"] == {"trace": "trace.npz", "can_log": "can.log", "figure": "report.png"}
    assert (folder / "report.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_trace_is_columnar_and_complete(record) -> None:
    folder, result = record
    with np.load(folder / "trace.npz") as trace:
        assert set(trace.files) == set(TRACE_COLUMNS)
        assert len(trace["t_s"]) == 12_000
        assert trace["af_hat"][-1] == pytest.approx(result.features["af"])


def test_can_log_is_read_back_by_python_can(record) -> None:
    folder, result = record
    frames = list(can.LogReader(str(folder / "can.log")))
    assert len(frames) == result.frames.count
    commands = [f for f in frames if f.arbitration_id == BENCH_CMD_ID]
    replies = [f for f in frames if f.arbitration_id == RIG_FEEDBACK_ID]
    assert len(commands) >= 12_000 and len(replies) >= 12_000
    assert all(len(f.data) == 8 for f in commands)
