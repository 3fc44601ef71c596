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
from edc_bench.records.reader import load_trace
from edc_bench.records.record import write_record
from edc_bench.engine.trace import TRACE_COLUMNS


@pytest.fixture(scope="module")
def record(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, object]:
    data = load_variant().model_dump()
    data["excitation"]["duration_s"] = 12.0
    result = run_simulated_test(parse_variant(data), "worn", 2, valve_id="V/0042 test", check_gains=False,
                                full_length=True)
    return write_record(result, tmp_path_factory.mktemp("records")), result


def test_record_folder_is_complete(record) -> None:
    folder, result = record
    assert sorted(p.name for p in folder.iterdir()) == ["can.log", "record.json", "report.png", "trace.mf4"]
    doc = json.loads((folder / "record.json").read_text())
    for key in ("verdict", "reasons", "valve_id", "variant", "software_version", "firmware_version", "features",
                "parameters", "converged", "identification", "timing", "loop", "config", "truth", "files"):
        assert key in doc, key
    assert doc["valve_id"] == "V/0042 test"
    assert doc["firmware_version"] == "1.0"
    assert doc["config"]["pump"]["name"] == "p-edc-default"
    assert doc["parameters"]["af"]["std"] > 0
    assert doc["timing"]["ticks"] == 12_000
    assert doc["files"] == {"trace": "trace.mf4", "can_log": "can.log", "figure": "report.png",
                            "figure_no_room": None}
    assert (folder / "report.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_trace_is_columnar_and_complete(record) -> None:
    folder, result = record
    trace = load_trace(folder)
    assert set(trace) == set(TRACE_COLUMNS)
    assert len(trace["t_s"]) == 12_000
    # the trace holds the online estimate; the feature is the period fit's (docs/method.md): close, not equal
    assert trace["af_hat"][-1] == pytest.approx(result.features.af, rel=0.02)
    for name, column in result.trace.items():  # bit for bit, in the trace's own types
        assert trace[name].dtype == column.dtype, name
        assert np.array_equal(trace[name], column, equal_nan=column.dtype.kind == "f"), name


def test_trace_mf4_opens_in_asammdf_with_units_and_the_can_frames(record) -> None:
    from asammdf import MDF

    folder, result = record
    with MDF(str(folder / "trace.mf4")) as mdf:
        rack = mdf.get("position_mm")
        assert rack.unit == "mm" and "rack position" in rack.comment
        assert np.array_equal(rack.samples, result.trace["position_mm"], equal_nan=True)
        assert np.array_equal(rack.timestamps, result.trace["t_s"])
        for name in TRACE_COLUMNS:
            if name == "t_s":
                continue
            channel = mdf.get(name)
            assert channel.comment and channel.unit, f"{name}: unit {channel.unit!r}, comment {channel.comment!r}"
        assert mdf.get("drive_v").unit == "V" and mdf.get("a1_hat").unit == "V s/mm"
        assert [g.channel_group.acq_name for g in mdf.groups] == ["trace", "CAN"]
        assert mdf.header.start_time.timestamp() == pytest.approx(
            result.frames.origin_unix_s + result.outcome.ticks_start_s, abs=1e-6)
    # the CAN frames are an ASAM bus-logging group: python-can reads them as it reads any MF4 log
    frames = list(can.LogReader(str(folder / "trace.mf4")))
    assert len(frames) == result.frames.count
    logged = list(can.LogReader(str(folder / "can.log")))
    assert [(f.arbitration_id, bytes(f.data), f.is_rx) for f in frames] == \
        [(f.arbitration_id, bytes(f.data), f.is_rx) for f in logged]
    assert frames[-1].timestamp == pytest.approx(logged[-1].timestamp, abs=1e-5)


def test_can_log_is_read_back_by_python_can(record) -> None:
    folder, result = record
    frames = list(can.LogReader(str(folder / "can.log")))
    assert len(frames) == result.frames.count
    commands = [f for f in frames if f.arbitration_id == BENCH_CMD_ID]
    replies = [f for f in frames if f.arbitration_id == RIG_FEEDBACK_ID]
    assert len(commands) >= 12_000 and len(replies) >= 12_000
    assert all(len(f.data) == 8 for f in commands)


def test_every_trace_column_has_an_mdf_channel_description() -> None:
    from edc_bench.records.mdf import CHANNELS, FLAG_CHANNELS

    assert set(CHANNELS) == set(TRACE_COLUMNS) - {"t_s"}
    assert FLAG_CHANNELS == {name for name, kind in TRACE_COLUMNS.items() if kind == "?"}
