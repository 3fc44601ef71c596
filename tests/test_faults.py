"""Every way a test can go wrong ends the same way: rig safe, a clear reason,
INVALID, and everything measured so far on disk (simulated time unless noted).

For each fault: the abort is decided at a known time; the first SAFE command
follows within 20 ms when the bus still carries frames, and in every case the
rig's amplifier is off within 25 ms of the bench's last command (its own
watchdog where the bus is gone); the record and the CAN log hold every tick
and frame up to the fault.
"""

from __future__ import annotations

import glob
import json
import os
import re
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import can
import pytest

from edc_bench.bench import BenchResult, run_bench_test
from edc_bench.config import load_variant
from edc_bench.diagnosis.verdict import Verdict
from edc_bench.physics.valve import parse_valve_spec
from edc_bench.protocol import BENCH_CMD_ID, Mode, default_icd
from edc_bench.records.record import write_record
from edc_bench.runtime.clock import SimulatedClock
from edc_bench.sim.inprocess import InProcessRig
from edc_bench.sim.rig import SimulatedRig
from edc_bench.testing.faults import RIG_FAULTS, FaultyBus, Rule, schedule_rig_fault

FAULT_AT_S = 2.5  # clock time of the fault (the rig boots in 0.2 s, the ticks start just after)

RIG_FAULT_REASONS = {
    "heartbeat_stops": "rig heartbeat lost",
    "rig_fault": "rig amplifier off while running (rig state FAULT, fault code SUPPLY_LOW)",
    "over_current": "rig fault: over-current",
    "lvdt_disconnected": "rig fault: LVDT fault",
    "lvdt_stuck": "rack does not follow its reference",
    "travel_limit": "rig fault: travel limit",
    "lvdt_out_of_range": "rig fault: LVDT fault",
    "current_nan": "rig fault: over-current",
}

BUS_FAULTS = {
    "drop-replies": (Rule("drop", FAULT_AT_S, direction="rx", can_id=0x121), "replies missing in a row"),
    "corrupt-replies": (Rule("corrupt", FAULT_AT_S, can_id=0x121), "replies missing in a row"),
    "stale-counter": (Rule("repeat", FAULT_AT_S, FAULT_AT_S + 0.05, direction="tx"), "replies missing in a row"),
    "delayed-replies": (Rule("delay", FAULT_AT_S, delay_s=0.0015), "replies missing in a row"),
    "reordered-frames": (Rule("reorder", FAULT_AT_S), "replies missing"),
    "send-error": (Rule("error", FAULT_AT_S, direction="tx"), "bus error: CanOperationError"),
    "receive-error": (Rule("error", FAULT_AT_S, direction="rx"), "bus error: CanOperationError"),
    "bus-off": (Rule("bus_off", FAULT_AT_S), "bus error: CanOperationError: injected: bus off"),
    "rig-cut-off": (Rule("cut", FAULT_AT_S), "replies missing in a row"),
}


def run_with(rule: Rule | None = None, rig_fault: str | None = None) -> tuple[BenchResult, SimulatedRig, SimulatedClock]:
    variant = load_variant()
    rig = SimulatedRig(variant, parse_valve_spec("worn", variant), 1)
    if rig_fault:
        schedule_rig_fault(rig, rig_fault, FAULT_AT_S)
    name = f"faults-{rule.kind if rule else rig_fault}-{time.perf_counter_ns()}"
    with can.Bus(interface="virtual", channel=name, preserve_timestamps=True) as bench, \
         can.Bus(interface="virtual", channel=name, preserve_timestamps=True) as rig_bus:
        clock = SimulatedClock(InProcessRig(rig_bus, rig))
        bus = FaultyBus(bench, clock.now_s, [rule] if rule else [])
        try:
            result = run_bench_test(bus, clock, variant, check_gains=False)
        finally:
            bus.shutdown()
        clock.wait_until(clock.now_s() + 0.025)  # 25 ms after the bench's last word
    return result, rig, clock


def check_safe_and_complete(result: BenchResult, rig: SimulatedRig, tmp_path: Path) -> None:
    outcome = result.outcome
    assert result.verdict == Verdict.INVALID
    assert result.classification is None
    assert outcome.abort_time_s is not None or outcome.abort_reason.startswith("bus error")
    # the rig's amplifier is off: by SAFE or by its own watchdog
    assert rig.plant.drive_v == 0.0
    assert rig.firmware.state.name in ("READY", "FAULT")
    # SAFE commanded within 20 ms of detection, when the bus still sends
    if outcome.abort_time_s is not None:
        detected = outcome.ticks_start_s + outcome.abort_time_s
        icd, frames = default_icd(), result.frames
        safe_times = [frames.t_s[k] for k in range(frames.count)
                      if not frames.rx[k] and frames.can_id[k] == BENCH_CMD_ID and frames.t_s[k] >= detected
                      and icd.bench_cmd.decode(bytes(frames.data[k]))[2] == Mode.SAFE]
        if safe_times:
            assert safe_times[0] - detected <= 0.020
    # everything measured so far is on disk
    folder = write_record(result, tmp_path, figure=False)
    doc = json.loads((folder / "record.json").read_text())
    assert doc["verdict"] == Verdict.INVALID and doc["loop"]["abort_reason"] == outcome.abort_reason
    assert len(list(can.LogReader(str(folder / "can.log")))) == result.frames.count
    import numpy as np

    with np.load(folder / "trace.npz") as trace:
        assert len(trace["t_s"]) == outcome.ticks_run > 1000
        if outcome.abort_time_s is not None:
            assert trace["t_s"][-1] == pytest.approx(outcome.abort_time_s)


@pytest.mark.parametrize("fault", RIG_FAULTS)
def test_rig_side_fault(fault: str, tmp_path: Path) -> None:
    result, rig, _ = run_with(rig_fault=fault)
    assert any(RIG_FAULT_REASONS[fault] in r for r in result.reasons), result.reasons
    check_safe_and_complete(result, rig, tmp_path)


@pytest.mark.parametrize("name", list(BUS_FAULTS))
def test_bus_fault(name: str, tmp_path: Path) -> None:
    rule, reason = BUS_FAULTS[name]
    result, rig, _ = run_with(rule=rule)
    assert any(reason in r for r in result.reasons), result.reasons
    check_safe_and_complete(result, rig, tmp_path)


def test_isolated_missing_replies_are_tolerated() -> None:
    """A few lost or corrupt replies are counted, the last sample reused, and the test goes on."""
    result, _, _ = run_with(rule=Rule("corrupt", FAULT_AT_S, FAULT_AT_S + 0.003, can_id=0x121))
    assert result.outcome.abort_reason is None
    assert 1 <= result.outcome.missed_replies <= 4
    assert result.outcome.bad_replies == result.outcome.missed_replies
    assert result.verdict == "FAIL"  # a worn valve, judged as usual


def test_rig_never_ready_is_one_clear_line(tmp_path: Path) -> None:
    variant = load_variant()
    rig = SimulatedRig(variant, parse_valve_spec("new", variant), 1)
    rig.firmware.heartbeat_enabled = False
    with can.Bus(interface="virtual", channel="never-ready", preserve_timestamps=True) as bench, \
         can.Bus(interface="virtual", channel="never-ready", preserve_timestamps=True) as rig_bus:
        result = run_bench_test(bench, SimulatedClock(InProcessRig(rig_bus, rig)), variant, check_gains=False)
    assert result.verdict == Verdict.INVALID
    assert result.reasons == ["aborted: rig not READY within 3 s (no heartbeat)"]


# -- the process: signals, and a killed test ----------------------------------------------

def _start_test(tmp_path: Path, *extra: str) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "edc_bench", "test", "--valve", "worn", "--out", "rec",
                             "--no-figure", *extra], cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)


def _wait_for_record_folder(tmp_path: Path, proc: subprocess.Popen) -> Path:
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline and proc.poll() is None:
        found = glob.glob(str(tmp_path / "rec" / "*" / "can.log"))
        if found and os.path.getsize(found[0]) > 0:
            return Path(found[0]).parent
        time.sleep(0.02)
    raise AssertionError("the test never started streaming its CAN log")


@pytest.mark.parametrize("signals", [[signal.SIGTERM], [signal.SIGINT, signal.SIGINT, signal.SIGTERM]],
                         ids=["sigterm", "ctrl-c-twice-then-sigterm"])
def test_interrupts_abort_safely_and_keep_the_record(tmp_path: Path, signals: list[int]) -> None:
    proc = _start_test(tmp_path)
    folder = _wait_for_record_folder(tmp_path, proc)
    for sig in signals:
        proc.send_signal(sig)
        time.sleep(0.005)
    out, err = proc.communicate(timeout=120)
    assert proc.returncode == 12, err
    assert "aborted: interrupted by the operator" in out
    doc = json.loads((folder / "record.json").read_text())
    assert doc["verdict"] == Verdict.INVALID and doc["loop"]["safe_confirmed"] is True
    # the CAN log holds every tick that ran: one RUN command each
    icd = default_icd()
    runs = sum(1 for f in can.LogReader(str(folder / "can.log"))
               if f.arbitration_id == BENCH_CMD_ID and icd.bench_cmd.decode(bytes(f.data))[2] == Mode.RUN)
    assert runs == doc["loop"]["ticks_run"] > 0


@pytest.mark.realtime
def test_sigkill_mid_test_leaves_rig_tripped_and_can_log_readable(tmp_path: Path) -> None:
    """SIGKILL a real-time test against the rig process: the rig's watchdog trips, the log reads back."""
    rig = subprocess.Popen([sys.executable, "-m", "edc_bench", "rig", "--listen", "127.0.0.1:0", "--valve", "worn"],
                           stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        port = int(re.search(r"127\.0\.0\.1:(\d+)", rig.stdout.readline()).group(1))
        source = (Path(__file__).parent.parent / "configs" / "p-edc-default.toml").read_text()
        (tmp_path / "kill.toml").write_text(source.replace('name = "p-edc-default"', 'name = "kill-test"')
                                            + "\n[acceptance]\nmax_missed_replies_in_row = 100\nmax_missed_reply_fraction = 0.5\n")
        test = _start_test(tmp_path, "--variant", str(tmp_path / "kill.toml"), "--interface", "slcan",
                           "--channel", f"socket://127.0.0.1:{port}")
        folder = _wait_for_record_folder(tmp_path, test)
        time.sleep(1.0)  # mid-test
        if test.poll() is not None:
            pytest.skip(f"the real-time test ended by itself before the kill (this machine stalled it): "
                        f"{test.communicate()[0][-300:]}")
        test.send_signal(signal.SIGKILL)
        test.wait(timeout=10)
        frames = list(can.LogReader(str(folder / "can.log")))
        icd = default_icd()
        modes = [icd.bench_cmd.decode(bytes(f.data))[2] for f in frames if f.arbitration_id == BENCH_CMD_ID]
        first_run = modes.index(Mode.RUN) if Mode.RUN in modes else len(modes)
        if Mode.SAFE in modes[first_run:]:
            pytest.skip("the real-time test had aborted by itself (SAFE sent) before the kill: this machine "
                        "stalled it; the SIGKILL found no running test")
        # the rig noticed: a monitor on the same rig sees its watchdog trip
        monitor = socket.create_connection(("127.0.0.1", port))
        monitor.sendall(b"O\r")
        buffer, state = b"", None
        deadline = time.monotonic() + 3.0
        while time.monotonic() < deadline and state is None:
            buffer += monitor.recv(4096)
            for line in re.findall(rb"t720(\d)([0-9A-F]+)\r", buffer):
                beat = icd.parse_heartbeat(bytes.fromhex(line[1].decode()))
                state = (beat.state.name, beat.fault_code.name)
        monitor.close()
        assert state == ("FAULT", "WATCHDOG")
        # the CAN log written so far reads back, and holds the test's frames
        print(f"{len(frames)} frames readable after SIGKILL")
        assert len(frames) > 100
        assert {f.arbitration_id for f in frames} >= {0x120, 0x121}
        assert not (folder / "record.json").exists()  # killed: no record, but the log survives
    finally:
        rig.send_signal(signal.SIGTERM)
        rig.wait(timeout=10)


def test_a_bug_in_the_tick_still_ends_safe_with_the_data(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from edc_bench.control.fel import FelController

    original = FelController.step

    def failing_step(self, k: int, measured_mm: float) -> float:
        if k == 1500:
            raise ZeroDivisionError("injected bug")
        return original(self, k, measured_mm)

    monkeypatch.setattr(FelController, "step", failing_step)
    result, rig, _ = run_with()
    assert result.outcome.abort_reason == "internal error: ZeroDivisionError: injected bug"
    assert "Traceback" in result.outcome.events[-1]
    assert result.outcome.ticks_run == 1500 and result.outcome.safe_confirmed
    assert rig.plant.drive_v == 0.0
    folder = write_record(result, tmp_path, figure=False)
    assert json.loads((folder / "record.json").read_text())["verdict"] == Verdict.INVALID
