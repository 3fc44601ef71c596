"""Every way a test can go wrong ends the same way: rig safe, a clear reason,
INVALID, and everything measured so far on disk (simulated time; operator
interrupts and a killed test process are in test_interrupts.py).

For each fault: the abort is decided at a known time; the first SAFE command
follows within 20 ms when the bus still carries frames, and in every case the
rig's amplifier is off within 25 ms of the bench's last command (its own
watchdog where the bus is gone); the record and the CAN log hold every tick
and frame up to the fault.
"""

from __future__ import annotations

import json
from pathlib import Path

import can
import numpy as np
import pytest
from helpers import check_safe_and_complete

from edc_bench.bench import BenchResult, BenchOptions, run_bench_test
from edc_bench.config import load_variant
from edc_bench.records.record import write_record
from edc_bench.runtime.clock import SimulatedClock
from edc_bench.sim.rig import SimulatedRig
from edc_bench.testing.faults import RIG_FAULTS, FaultyBus, Rule, schedule_rig_fault
from edc_bench.verdict.verdicts import Verdict

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
    # beyond acceptance.max_reply_age_ms (2 ms): too old to use (1.5 ms is fine: tests/runtime/test_pipelining.py)
    "delayed-replies": (Rule("delay", FAULT_AT_S, delay_s=0.005), "older than acceptance.max_reply_age_ms"),
    "send-error": (Rule("error", FAULT_AT_S, direction="tx"), "bus error: CanOperationError"),
    "receive-error": (Rule("error", FAULT_AT_S, direction="rx"), "bus error: CanOperationError"),
    "bus-off": (Rule("bus_off", FAULT_AT_S), "bus error: CanOperationError: injected: bus off"),
    "rig-cut-off": (Rule("cut", FAULT_AT_S), "replies missing in a row"),
}


def run_with(simulated_bench, rule: Rule | None = None,
             rig_fault: str | None = None) -> tuple[BenchResult, SimulatedRig, SimulatedClock]:
    variant = load_variant()
    bench, clock, rig = simulated_bench(variant, "worn", 1, interface="virtual")
    if rig_fault:
        schedule_rig_fault(rig, rig_fault, FAULT_AT_S)
    bus = FaultyBus(bench, clock.now_s, [rule] if rule else [])
    try:
        result = run_bench_test(bus, clock, variant, BenchOptions(check_gains=False))
    finally:
        bus.shutdown()
    clock.wait_until(clock.now_s() + 0.025)  # 25 ms after the bench's last word
    return result, rig, clock


@pytest.mark.parametrize("fault", RIG_FAULTS)
def test_rig_side_fault(fault: str, tmp_path: Path, simulated_bench) -> None:
    result, rig, _ = run_with(simulated_bench, rig_fault=fault)
    assert any(RIG_FAULT_REASONS[fault] in r for r in result.reasons), result.reasons
    check_safe_and_complete(result, rig, tmp_path)


@pytest.mark.parametrize("name", list(BUS_FAULTS))
def test_bus_fault(name: str, tmp_path: Path, simulated_bench) -> None:
    rule, reason = BUS_FAULTS[name]
    result, rig, _ = run_with(simulated_bench, rule=rule)
    assert any(reason in r for r in result.reasons), result.reasons
    check_safe_and_complete(result, rig, tmp_path)


def test_isolated_missing_replies_are_tolerated(simulated_bench) -> None:
    """A few lost or corrupt replies are counted, the last sample reused, and the test goes on."""
    result, _, _ = run_with(simulated_bench, rule=Rule("corrupt", FAULT_AT_S, FAULT_AT_S + 0.003, can_id=0x121))
    assert result.outcome.abort_reason is None
    assert 1 <= result.outcome.missed_replies <= 4
    assert result.outcome.bad_replies == result.outcome.missed_replies
    assert result.verdict == "FAIL"  # a worn valve, judged as usual


@pytest.mark.parametrize("held_ms", [6.0, 8.0])
def test_a_link_that_holds_its_replies_back_once_does_not_end_the_test(simulated_bench, held_ms: float) -> None:
    """For 10 ms every reply comes ``held_ms`` late (a USB adapter's host controller, a busy rig): more than 5
    in a row too old to use, so the PID held, but the link never went silent. The test goes on (before: aborted,
    "6 replies missing in a row"); a link that stays slow still ends it (test_pipelining.py), a silent one too.
    (Replies held back 10 ms or more look like silence: 6 commands expire before the first comes.)"""
    rule = Rule("delay", FAULT_AT_S, FAULT_AT_S + 0.010, direction="rx", can_id=0x121, delay_s=held_ms * 1e-3)
    result, _, _ = run_with(simulated_bench, rule=rule)
    o = result.outcome
    assert o.abort_reason is None, o.abort_reason
    assert o.max_missed_in_row > 5 and o.replies_too_old >= 6  # what the old rule ended the test for
    assert o.max_unanswered_in_row <= 5
    assert result.verdict == "FAIL"  # a worn valve, judged as usual


def test_a_rig_that_goes_silent_ends_the_test_as_before(simulated_bench) -> None:
    result, _, _ = run_with(simulated_bench, rule=Rule("drop", FAULT_AT_S, direction="rx", can_id=0x121))
    assert result.outcome.abort_reason == "6 replies missing in a row (limit 5): the rig stopped answering"
    # decided when the sixth command without a reply passed the age limit (4 ticks): 10 ticks after the last reply
    answered = np.flatnonzero(result.trace["reply_ok"].astype(bool))
    assert result.outcome.abort_time_s - result.trace["t_s"][answered[-1]] == pytest.approx(0.010, abs=0.0015)


def test_rig_never_ready_is_one_clear_line(tmp_path: Path, simulated_bench) -> None:
    variant = load_variant()
    bench, clock, rig = simulated_bench(variant, "new", 1, interface="virtual")
    rig.firmware.heartbeat_enabled = False
    result = run_bench_test(bench, clock, variant, BenchOptions(check_gains=False))
    assert result.verdict == Verdict.INVALID
    assert result.reasons == ["aborted: rig not READY within 3 s (no heartbeat)"]


def test_a_bug_in_the_tick_still_ends_safe_with_the_data(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                         simulated_bench) -> None:
    from edc_bench.control import law

    original = law.feedforward_v
    calls = []

    def failing_feedforward(*args, **kwargs):
        # the controller's law is looked up at every call
        calls.append(1)
        if len(calls) == 1501:  # tick 1500's step
            raise ZeroDivisionError("injected bug")
        return original(*args, **kwargs)

    monkeypatch.setattr(law, "feedforward_v", failing_feedforward)
    result, rig, _ = run_with(simulated_bench)
    assert result.outcome.abort_reason == "internal error: ZeroDivisionError: injected bug"
    assert "Traceback" in result.outcome.events[-1]
    assert result.outcome.ticks_run == 1500 and result.outcome.safe_confirmed
    assert rig.plant.drive_v == 0.0
    folder = write_record(result, tmp_path, figure=False)
    assert json.loads((folder / "record.json").read_text())["verdict"] == Verdict.INVALID


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


def test_bus_error_mid_test_ends_invalid_with_the_data_so_far(tmp_path: Path, simulated_bench) -> None:
    variant = load_variant()
    bench, clock, _ = simulated_bench(variant, "worn", 1, interface="virtual")
    result = run_bench_test(FailingBus(bench, 3000), clock, variant, BenchOptions(check_gains=False))
    assert result.verdict == "INVALID"
    assert any("bus error: CanOperationError" in r for r in result.reasons)
    assert 2900 < result.timing.ticks < 3000  # what was measured before the fault is kept
    folder = write_record(result, tmp_path)
    assert json.loads((folder / "record.json").read_text())["verdict"] == "INVALID"
    assert len(list(can.LogReader(str(folder / "can.log")))) == result.frames.count



@pytest.mark.parametrize("name", ["p-edc-default", "p-edc-long", "p-edc-hard"])
def test_a_stuck_sensor_ends_the_test_100_ticks_after_the_rack_reads_2_mm_off(simulated_bench, name: str) -> None:
    """Caught by the bench, as a stuck sensor, before the PID winds the coil up to the rig's over-current trip
    (165 ticks on p-edc-default; a limit of 200 ticks let the rig trip first)."""
    variant = load_variant(name)
    bench, clock, rig = simulated_bench(variant, "worn", 1, interface="virtual")
    schedule_rig_fault(rig, "lvdt_stuck", FAULT_AT_S)
    result = run_bench_test(bench, clock, variant, BenchOptions(check_gains=False))
    reason = result.outcome.abort_reason
    assert reason.startswith("rack does not follow its reference: more than 2 mm off for 100 ticks, moving 0.00 mm")
    assert reason.endswith("(stuck rack or sensor)")
    off = np.abs(result.trace["reference_mm"] - result.trace["position_mm"]) > 2.0
    assert off[-100:].all() and not off[-101]  # the whole run, and no more, in the trace
    assert np.abs(result.trace["current_a"]).max() < 0.5 * variant.rig.over_current_a  # 4.8-6.4 A of 15
