"""The record folder, the CLI's `test` command, and a real-time test over slcan."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import can
import numpy as np
import pytest

from edc_bench.bench import run_simulated_test
from edc_bench.config import load_variant, parse_variant
from edc_bench.physics.feedforward import feedforward_truth
from edc_bench.physics.valve import parse_valve_spec, plant_parameters
from edc_bench.protocol import BENCH_CMD_ID, RIG_FEEDBACK_ID
from edc_bench.records.record import write_record
from edc_bench.runtime.trace import TRACE_COLUMNS


def edc_bench(*args: str, cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "edc_bench", *args], capture_output=True, text=True, cwd=cwd,
                          timeout=300)


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


def test_cli_test_json_summary(tmp_path: Path) -> None:
    proc = edc_bench("test", "--valve", "faulty", "--seed", "3", "--duration-s", "10", "--json", "--out", "rec",
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
        (["--interface", "nosuchbus"], "cannot open the CAN bus (interface=nosuchbus)", 3),
    ],
)
def test_cli_bad_input_is_one_clear_line(tmp_path: Path, args: list[str], message: str, code: int) -> None:
    proc = edc_bench("test", *args, cwd=tmp_path)
    assert proc.returncode == code
    assert message in proc.stderr
    assert "Traceback" not in proc.stderr


def test_cli_refuses_unstable_gains(tmp_path: Path) -> None:
    source = (Path(__file__).parent.parent / "configs" / "p-edc-default.toml").read_text()
    bad = tmp_path / "hot.toml"
    bad.write_text(source.replace("kp_v_per_mm = 0.6", "kp_v_per_mm = 3.0").replace('name = "p-edc-default"',
                                                                                      'name = "hot"'))
    proc = edc_bench("test", "--variant", str(bad), cwd=tmp_path)
    assert proc.returncode == 2
    assert "unstable" in proc.stderr and "Traceback" not in proc.stderr


STEAL_LIMIT_S = 0.15  # CPU steal during one 12 s run above which real-time figures say nothing about the code
STALL_LIMIT_US = 10_000  # a bench tick this late means the machine did not run the process


def disturbed(timing: dict) -> bool:
    """The machine, not the code, decided this run: heavy steal, or the bench process not scheduled."""
    worst = timing["lateness_max_us"]
    return timing["cpu_steal_s"] >= STEAL_LIMIT_S or (worst is not None and worst >= STALL_LIMIT_US)


@pytest.mark.realtime
def test_realtime_test_over_slcan_against_the_rig_process(tmp_path: Path) -> None:
    """`edc-bench test --realtime` starts `edc-bench rig` and drives it over slcan/TCP at 1 kHz.

    This shared 2-core VM stalls processes for milliseconds at times (CPU steal, slow
    wake-ups); the default acceptance aborts after 5 replies missing in a row. This test
    checks the real-time path, so its variant tolerates 50 in a row; the record still
    counts every missed reply and overrun. Up to three attempts, each reported. A run that
    does not complete although the machine ran it undisturbed (little CPU steal, no tick
    10 ms late) fails the test; if every attempt was disturbed, the test is skipped with
    the measured figures.
    """
    source = (Path(__file__).parent.parent / "configs" / "p-edc-default.toml").read_text()
    variant_file = tmp_path / "rt.toml"
    variant_file.write_text(source.replace('name = "p-edc-default"', 'name = "rt-test"')
                            + "\n[acceptance]\nmax_missed_replies_in_row = 50\nmax_overrun_fraction = 0.2\n"
                            "max_missed_reply_fraction = 0.2\n")
    attempts = []
    for attempt in range(3):
        proc = edc_bench("test", "--realtime", "--variant", str(variant_file), "--valve", "worn",
                         "--duration-s", "12", "--json", "--no-figure", "--out", "rec", cwd=tmp_path)
        assert proc.returncode in (11, 12), proc.stderr  # a worn valve: FAIL, or INVALID if disturbed
        summary = json.loads(proc.stdout)
        timing = summary["timing"]
        attempts.append(timing)
        print(f"attempt {attempt + 1}: {summary['verdict']} {summary['reasons']} timing {timing}")
        # every run, complete or not, leaves its timing statistics in the record and the rig safe
        assert summary["clock"] == "real-time"
        for key in ("lateness_p50_us", "lateness_p99_us", "lateness_max_us", "overruns", "missed_replies",
                    "cpu_steal_s"):
            assert key in timing
        doc = json.loads(Path(tmp_path / summary["record_dir"], "record.json").read_text())
        assert doc["timing"] == timing
        assert doc["loop"]["safe_confirmed"] is True
        assert doc["firmware_version"] == "1.0"
        if timing["ticks"] == 12_000:
            break
        if not disturbed(timing):
            pytest.fail(f"real-time test did not complete on an undisturbed machine: {summary['reasons']} {timing}")
    else:
        pytest.skip("every attempt was disturbed by this machine: " + "; ".join(
            f"{t['ticks']} ticks, steal {t['cpu_steal_s']:.2f} s, worst tick {t['lateness_max_us'] / 1e3:.1f} ms late"
            for t in attempts))
    assert timing["missed_replies"] < 1200
    # identification in real time: the rig process runs the worn preset, whose truth is known here
    variant = load_variant()
    truth = feedforward_truth(plant_parameters(variant, parse_valve_spec("worn", variant)))
    assert abs(summary["features"]["af"] / truth.af - 1) < 0.08
    assert abs(summary["features"]["a1"] / truth.a1 - 1) < 0.20


class FailingBus(can.BusABC):
    """A bus whose sends start failing after a number of frames (a cable pulled)."""

    def __init__(self, inner: can.BusABC, fail_after: int) -> None:
        self.inner = inner
        self.sent = 0
        self.fail_after = fail_after
        super().__init__(channel="failing")

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        self.sent += 1
        if self.sent > self.fail_after:
            raise can.CanOperationError("transmit buffer full")
        self.inner.send(msg, timeout)

    def _recv_internal(self, timeout: float | None):
        return self.inner.recv(timeout), False


def test_bus_error_mid_test_ends_invalid_with_the_data_so_far(tmp_path: Path) -> None:
    from edc_bench.bench import run_bench_test
    from edc_bench.runtime.clock import SimulatedClock
    from edc_bench.sim.inprocess import InProcessRig
    from edc_bench.sim.rig import SimulatedRig

    variant = load_variant()
    rig = SimulatedRig(variant, parse_valve_spec("worn", variant), 1)
    with can.Bus(interface="virtual", channel="fail-test", preserve_timestamps=True) as bench, \
         can.Bus(interface="virtual", channel="fail-test", preserve_timestamps=True) as rig_bus:
        result = run_bench_test(FailingBus(bench, 3000), SimulatedClock(InProcessRig(rig_bus, rig)), variant,
                                check_gains=False)
    assert result.verdict == "INVALID"
    assert any("bus error: CanOperationError" in r for r in result.reasons)
    assert 2900 < result.timing["ticks"] < 3000  # what was measured before the fault is kept
    folder = write_record(result, tmp_path)
    assert json.loads((folder / "record.json").read_text())["verdict"] == "INVALID"
    assert len(list(can.LogReader(str(folder / "can.log")))) == result.frames.count
