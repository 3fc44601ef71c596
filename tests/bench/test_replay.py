"""Replay rebuilds a test from its CAN log and reproduces what it recorded, exactly."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import can
import pytest
from helpers import rewrite_record_json

from edc_bench.bench import BenchOptions, run_bench_test, run_simulated_test
from edc_bench.config import load_variant, parse_variant
from edc_bench.errors import ConfigError
from edc_bench.records.record import write_record
from edc_bench.replay import replay_record
from edc_bench.testing.faults import FaultyBus, Rule


@pytest.mark.parametrize(("valve", "seed", "verdict"), [("new", 4, "PASS"), ("worn", 5, "FAIL")])
def test_replay_reproduces_a_simulated_test_exactly(tmp_path: Path, valve: str, seed: int, verdict: str) -> None:
    result = run_simulated_test(load_variant(), valve, seed)
    assert result.verdict == verdict
    folder = write_record(result, tmp_path, figure=False)
    report = replay_record(folder)
    assert report.reproduced, report.differences
    assert report.judged.verdict == verdict
    for name, entry in result.parameters.items():
        assert report.judged.parameters[name].value == entry.value
        assert report.judged.parameters[name].std == entry.std
    assert report.judged.classification.probability_faulty == result.classification.probability_faulty
    assert report.judged.classification.distance == result.classification.distance
    assert report.run.max_drive_deviation_v <= 0.0005 + 1e-9


def test_a_record_of_an_older_edc_bench_replays_under_today_s_rules(tmp_path: Path) -> None:
    """Records made before #11's review hold [acceptance].max_period_spread_rel, since retired."""
    folder = write_record(run_simulated_test(load_variant(), "worn", 5), tmp_path, figure=False)
    path = folder / "record.json"
    doc = json.loads(path.read_text())
    doc["config"]["acceptance"]["max_period_spread_rel"] = 0.02
    rewrite_record_json(folder, doc)  # as the older edc-bench wrote it
    report = replay_record(folder)
    assert report.reproduced, report.differences


def _run_with_lost_replies(simulated_bench, rule: Rule):
    variant = load_variant()
    bench, clock, _ = simulated_bench(variant, "worn", 2)
    return run_bench_test(FaultyBus(bench, clock.now_s, [rule]), clock, variant, BenchOptions(check_gains=False))


def test_replay_follows_missing_replies_and_aborts(tmp_path: Path, simulated_bench) -> None:
    # two replies lost: the test goes on with the last position, as the loop did
    brief = _run_with_lost_replies(simulated_bench, Rule("drop", 5.0, 5.0025, direction="rx", can_id=0x121))
    assert brief.outcome.missed_replies >= 2 and brief.outcome.abort_reason is None
    # replies lost for good: the test aborts (INVALID); the partial run replays too
    lost = _run_with_lost_replies(simulated_bench, Rule("drop", 6.0, direction="rx", can_id=0x121))
    assert lost.verdict == "INVALID"
    for result, name in ((brief, "brief"), (lost, "lost")):
        report = replay_record(write_record(result, tmp_path / name, figure=False))
        assert report.reproduced, report.differences
        assert report.run.missed_replies == result.outcome.missed_replies


def test_replay_command_and_raw_log(tmp_path: Path) -> None:
    result = run_simulated_test(load_variant(), "worn", 6)
    folder = write_record(result, tmp_path, figure=False)
    cmd = [sys.executable, "-m", "edc_bench", "replay"]
    proc = subprocess.run([*cmd, str(folder), "--json"], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    out = json.loads(proc.stdout)
    assert out["reproduced"] is True and out["verdict"] == "FAIL"
    # a raw log with its variant: same verdict and parameters (timing is not in a log)
    proc = subprocess.run([*cmd, "--can-log", str(folder / "can.log"), "--variant", "p-edc-default", "--json"],
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 11, proc.stderr
    raw = json.loads(proc.stdout)
    assert raw["verdict"] == "FAIL" and raw["features"] == out["features"]
    # a record altered after the fact is caught
    record = json.loads((folder / "record.json").read_text())
    record["parameters"]["af"]["value"] *= 1.01
    altered = tmp_path / "altered"
    shutil.copytree(folder, altered)
    (altered / "record.json").write_text(json.dumps(record))
    proc = subprocess.run([*cmd, str(altered)], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 13
    assert "NOT reproduced" in proc.stdout and "af value" in proc.stdout


def test_replay_refuses_logs_it_cannot_explain(tmp_path: Path) -> None:
    result = run_simulated_test(load_variant(), "new", 7)
    folder = write_record(result, tmp_path, figure=False)
    cmd = [sys.executable, "-m", "edc_bench", "replay"]
    # another variant drives differently: refused, not misjudged
    proc = subprocess.run([*cmd, "--can-log", str(folder / "can.log"), "--variant", "p-edc-long"],
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 2
    assert "error:" in proc.stderr and "Traceback" not in proc.stderr
    for args, message in (([str(tmp_path / "nope")], "no such record folder"),
                          (["--can-log", str(folder / "can.log")], "--can-log needs --variant"),
                          ([], "give a record folder")):
        proc = subprocess.run([*cmd, *args], capture_output=True, text=True, timeout=120)
        assert proc.returncode == 2 and message in proc.stderr, proc.stderr
    empty = tmp_path / "empty.log"
    with can.CanutilsLogWriter(str(empty)) as writer:
        writer.on_message_received(can.Message(arbitration_id=0x720, data=bytes(8), is_extended_id=False))
    with pytest.raises(ConfigError, match="no bench test"):
        from edc_bench.replay import replay_can_log

        replay_can_log(empty, load_variant())


@pytest.mark.slow  # seconds: CI's slow pass runs it (the default suite stays under 5 minutes on CI)
def test_a_record_replays_from_its_log_converted_to_asc_and_blf_and_from_its_mf4(tmp_path: Path) -> None:
    # the log a technician sends converted by python-can's own tool, or the frames in trace.mf4: same verdict,
    # same parameters, bit for bit (these formats round timestamps; replay goes by the frames' order)
    data = load_variant().model_dump()
    data["excitation"]["duration_s"] = 20.0  # long enough to converge and be judged; the suite's time is short
    result = run_simulated_test(parse_variant(data), "worn", 6, check_gains=False)
    folder = write_record(result, tmp_path, figure=False)
    logs = [folder / "trace.mf4"]
    for suffix in (".asc", ".blf"):
        converted = tmp_path / f"converted{suffix}"
        proc = subprocess.run([sys.executable, "-m", "can.logconvert", str(folder / "can.log"), str(converted)],
                              capture_output=True, text=True, timeout=300)
        assert proc.returncode == 0, proc.stderr
        logs.append(converted)
    for log in logs:
        report = replay_record(folder, can_log=log)
        assert report.reproduced, (log.name, report.differences)
        assert report.judged.verdict == result.verdict == "FAIL"
        assert report.judged.parameters["af"].value == result.parameters["af"].value
    # the command: a record with another log of it
    proc = subprocess.run([sys.executable, "-m", "edc_bench", "replay", str(folder), "--can-log", str(logs[1]),
                           "--json"], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert json.loads(proc.stdout)["reproduced"] is True


@pytest.mark.parametrize(("name", "content", "expected"), [
    ("frames.txt", b"(0.0) can0 120#00\n", "not a CAN log format"),
    ("broken.blf", b"LOGG\x00\x01garbage" * 10, "holds no CAN data frames \\(Vector BLF\\)"),
    ("broken.asc", b"\xff\xfe not ascii at all \x00\x01", "not a readable Vector ASC"),
    ("broken.mf4", b"MDF     4.10    " + b"\x00" * 40, "not a readable ASAM MDF"),
])
def test_a_log_that_cannot_be_read_is_named_with_its_format(tmp_path: Path, name: str, content: bytes,
                                                             expected: str) -> None:
    from edc_bench.records.reader import read_can_log

    path = tmp_path / name
    path.write_bytes(content)
    with pytest.raises(ConfigError, match=expected):
        read_can_log(path)


def test_a_record_of_an_older_schema_is_compared_to_a_tolerance_a_new_one_to_the_bit(tmp_path: Path) -> None:
    """Records written before the controller's sums were reordered differ from today's replay in the last bits
    (1e-13): they are compared to 1e-9 relative and said to be; a record of today's schema must match exactly."""
    folder = write_record(run_simulated_test(load_variant(), "new", 5), tmp_path, figure=False)
    path = folder / "record.json"
    doc = json.loads(path.read_text())
    doc["parameters"]["a1"]["value"] *= 1.0 + 1e-13
    rewrite_record_json(folder, doc)  # records as an edc-bench wrote them (manifest and all), not edited
    report = replay_record(folder)
    assert not report.reproduced and report.differences[0].startswith("a1 value"), report.differences
    doc["schema"] = 3
    rewrite_record_json(folder, doc)
    report = replay_record(folder)
    assert report.reproduced and "record schema 3" in report.notes[0]
    doc["parameters"]["a1"]["value"] *= 1.0 + 1e-6  # beyond the tolerance: a different run
    rewrite_record_json(folder, doc)
    assert not replay_record(folder).reproduced


def test_a_record_from_before_the_core_rows_fit_says_why_its_numbers_may_differ(tmp_path: Path, capsys) -> None:
    """Records of schema 5 and older hold af and a1 from the fit over every used row; replay identifies as today's
    edc-bench does (the core rows), and says so beside whatever differs, on the command line too."""
    from edc_bench.cli import main

    folder = write_record(run_simulated_test(load_variant(), "new", 5), tmp_path, figure=False)
    doc = json.loads((folder / "record.json").read_text())
    assert doc["schema"] >= 6 and not any("every used row" in n for n in replay_record(folder).notes)
    doc["schema"] = 5
    doc["parameters"]["a1"]["value"] *= 1.01  # as the fit over every used row had it
    rewrite_record_json(folder, doc)
    report = replay_record(folder)
    assert not report.reproduced and report.differences[0].startswith("a1 value"), report.differences
    assert any("fit over every used row (record schema 5)" in n for n in report.notes), report.notes
    code = main(["replay", str(folder)])
    out = capsys.readouterr().out
    assert code != 0 and "NOT reproduced:" in out and "note: recorded by an edc-bench whose af and a1" in out


def test_a_record_whose_part_diagnosis_was_older_says_why_its_part_may_differ(tmp_path: Path) -> None:
    """Schema 11 read a sensor 5 % long on p-edc-hard (its solenoid pulls +/-10 % across the swing) as a PASS, part
    none; today's diagnosis names the sensor. Such a record replays with the difference and a note saying why; a
    record of today's schema has no such note."""
    from edc_bench.verdict.part_sections import Signature

    result = run_simulated_test(load_variant("p-edc-hard"), "new", 3, sensor_fault="gain=1.05")
    folder = write_record(result, tmp_path, figure=False)
    doc = json.loads((folder / "record.json").read_text())
    assert doc["schema"] >= 12 and doc["part"]["part"] == "rack-travel sensor"
    assert replay_record(folder).reproduced and not any("part diagnosis" in n for n in replay_record(folder).notes)
    doc["schema"] = 11
    doc["part"]["part"] = "none"  # as schema 11's diagnosis had it
    gain = next(f for f in doc["part"]["findings"] if f["signature"] == Signature.SENSOR_GAIN)
    gain["figure"], gain["beyond"] = 0.037, False
    rewrite_record_json(folder, doc)
    report = replay_record(folder)
    assert not report.reproduced and "part at fault: recorded none, replayed rack-travel sensor" in report.differences
    assert any("part diagnosis read a sensor's gain without the solenoid's pull" in n for n in report.notes)


def test_a_record_from_before_the_pumps_spring_tolerance_says_why_its_part_may_differ(tmp_path: Path) -> None:
    """Schema 12 named the rack-travel sensor of a sound pump whose return spring was 3 % stiffer ('not linear');
    today's allows the spring within the type's tolerance and names no part. Such a record replays with the
    difference and a note saying why."""
    from edc_bench.verdict.part_sections import Signature

    result = run_simulated_test(load_variant(), "new", 3, rack_fault="spring_rel=0.03")
    folder = write_record(result, tmp_path, figure=False)
    doc = json.loads((folder / "record.json").read_text())
    assert doc["schema"] >= 13 and doc["part"]["part"] == "none"
    assert doc["part"]["compared_with"]["pumps"] == 0
    assert replay_record(folder).reproduced
    doc["schema"] = 12
    doc["part"]["part"] = "rack-travel sensor"  # as schema 12's diagnosis had it
    linearity = next(f for f in doc["part"]["findings"] if f["signature"] == Signature.SENSOR_LINEARITY)
    linearity["figure"], linearity["beyond"] = 0.1211, True
    rewrite_record_json(folder, doc)
    report = replay_record(folder)
    assert not report.reproduced and "part at fault: recorded rack-travel sensor, replayed none" in report.differences
    assert any("did not allow the pump's return spring to differ" in n for n in report.notes), report.notes
