"""The rig firmware as a state machine, on fake hardware: the Python prototype and the C core, the same tests.

The C core's tests skip, saying how to build it, where its library is not built (CI builds it)."""

from __future__ import annotations

import math

import pytest

from edc_bench.protocol import BENCH_CMD_ID, RIG_FEEDBACK_ID, RIG_HEARTBEAT_ID, FaultCode, Icd, Mode, RigState, e2e_crc
from firmware_proto.c_firmware import CRigFirmware, c_firmware_available, library_path
from firmware_proto.firmware import FirmwareLimits, RigFirmware


class FakeHardware:
    """Records every call, returns the sample values it is given."""

    def __init__(self) -> None:
        self.position_mm = 10.0
        self.current_a = 3.0
        self.supply_v = 24.0
        self.drive_v = 0.0
        self.calls: list[str] = []

    def sample_position_mm(self) -> float:
        self.calls.append("sample_position")
        return self.position_mm

    def sample_current_a(self) -> float:
        self.calls.append("sample_current")
        return self.current_a

    def set_drive_v(self, drive_v: float) -> None:
        self.calls.append(f"drive {drive_v:g}")
        self.drive_v = drive_v

    def supply_voltage_v(self) -> float:
        return self.supply_v


LIMITS = FirmwareLimits(drive_limit_v=12.0, over_current_a=8.0, travel_min_mm=-0.5, travel_max_mm=19.5,
                        lvdt_min_mm=-1.0, lvdt_max_mm=21.0, supply_min_v=18.0, watchdog_s=0.020,
                        heartbeat_period_s=0.100, boot_s=0.200)


class Harness:
    def __init__(self, icd: Icd, firmware: str = "python") -> None:
        self.icd = icd
        self.hw = FakeHardware()
        kind = CRigFirmware if firmware == "c" else RigFirmware
        self.fw = kind(self.hw, LIMITS, start_s=0.0, icd=icd)
        self.t = 0.0
        self.counter = 0

    def until(self, t_s: float) -> list[tuple[int, bytes]]:
        out = []
        while self.fw.next_deadline_s() <= t_s:
            out += self.fw.on_time(self.fw.next_deadline_s())
        self.t = t_s
        return out

    def send(self, mode: int, drive_v: float = 0.0, counter: int | None = None, payload: bytes | None = None):
        if counter is None:
            self.counter = (self.counter + 1) % 256
            counter = self.counter
        data = payload if payload is not None else self.icd.make_bench_cmd(counter, mode, drive_v, 10.0)
        return self.fw.on_frame(BENCH_CMD_ID, data, self.t)

    def feedback(self, frames):
        replies = [self.icd.parse_rig_feedback(d) for i, d in frames if i == RIG_FEEDBACK_ID]
        assert len(replies) == 1, frames
        return replies[0]

    def states(self, frames) -> list[RigState]:
        return [self.icd.parse_heartbeat(d).state for i, d in frames if i == RIG_HEARTBEAT_ID]


@pytest.fixture(params=["python", "c"])
def rig(icd: Icd, request: pytest.FixtureRequest) -> Harness:
    if request.param == "c" and not c_firmware_available():
        pytest.skip(f"the C firmware is not built ({library_path()}): this machine has no make or cc")
    return Harness(icd, request.param)


def ready(rig: Harness) -> Harness:
    rig.until(0.25)
    assert rig.fw.state is RigState.READY
    return rig


def test_boot_then_ready_with_heartbeats_at_10_hz(rig: Harness) -> None:
    frames = rig.until(0.0)
    assert rig.states(frames) == [RigState.BOOT]
    assert rig.send(Mode.SAFE) == []  # commands are ignored while booting
    assert rig.fw.counters.ignored_in_boot == 1
    frames = rig.until(1.0)
    states = rig.states(frames)
    # beats at 0.1 ... 1.0 plus one at once when READY is entered
    assert len(states) == 11
    assert states[:2] == [RigState.BOOT, RigState.READY]
    assert set(states[2:]) == {RigState.READY}


def test_run_command_samples_before_applying_drive_and_echoes_counter(rig: Harness) -> None:
    ready(rig)
    rig.hw.calls.clear()
    frames = rig.send(Mode.RUN, 3.5, counter=42)
    reply = rig.feedback(frames)
    assert reply.counter == 42
    assert rig.hw.calls[:2] == ["sample_position", "sample_current"]
    assert rig.hw.calls[-1] == "drive 3.5"
    assert (reply.position_mm, reply.current_a) == (10.0, 3.0)
    assert reply.amp_enabled and not reply.any_fault
    assert rig.states(frames) == [RigState.RUNNING]  # state change announced at once


def test_drive_is_clamped_to_the_limit(rig: Harness) -> None:
    ready(rig)
    rig.send(Mode.RUN, 30.0)
    assert rig.hw.drive_v == LIMITS.drive_limit_v
    rig.send(Mode.RUN, -30.0)
    assert rig.hw.drive_v == -LIMITS.drive_limit_v


def test_bad_crc_is_ignored_and_counted_without_reply(rig: Harness, icd: Icd) -> None:
    ready(rig)
    good = icd.make_bench_cmd(1, Mode.RUN, 3.0, 10.0)
    bad = bytes([good[0] ^ 0x01]) + good[1:]
    assert rig.send(Mode.RUN, payload=bad) == []
    assert rig.fw.counters.bad_crc == 1
    assert rig.hw.drive_v == 0.0
    assert rig.fw.on_frame(BENCH_CMD_ID, b"\x00" * 3, rig.t) == []
    assert rig.fw.counters.bad_length == 1


def test_repeated_and_stale_counters_are_ignored_without_reply(rig: Harness) -> None:
    ready(rig)
    rig.feedback(rig.send(Mode.RUN, 1.0, counter=10))
    assert rig.send(Mode.RUN, 2.0, counter=10) == []
    assert rig.fw.counters.repeated_counter == 1
    assert rig.send(Mode.RUN, 2.0, counter=9) == []
    assert rig.send(Mode.RUN, 2.0, counter=200) == []  # 190 behind modulo 256 is old
    assert rig.fw.counters.stale_counter == 2
    assert rig.hw.drive_v == 1.0
    assert rig.feedback(rig.send(Mode.RUN, 2.0, counter=13)).counter == 13  # skipping ahead is fine
    assert rig.feedback(rig.send(Mode.RUN, 2.0, counter=14)).counter == 14
    rig.counter = 255
    assert rig.send(Mode.RUN, 2.0, counter=255) == []  # 241 ahead: stale
    for c in (15, 100, 200, 255, 0, 1):  # the counter wraps
        assert rig.feedback(rig.send(Mode.RUN, 2.0, counter=c)).counter == c


def test_safe_command_may_resynchronise_the_counter_when_not_running(rig: Harness) -> None:
    ready(rig)
    rig.feedback(rig.send(Mode.RUN, 1.0, counter=100))
    rig.feedback(rig.send(Mode.SAFE, counter=101))
    # a new bench session starts counting at 0: accepted because the amplifier is off
    assert rig.feedback(rig.send(Mode.SAFE, counter=0)).counter == 0
    assert rig.feedback(rig.send(Mode.RUN, 1.0, counter=1)).counter == 1


def test_watchdog_trips_after_20_ms_and_latches_until_safe(rig: Harness) -> None:
    ready(rig)
    rig.send(Mode.RUN, 3.0)
    t_last = rig.t
    assert RigState.FAULT not in rig.states(rig.until(t_last + 0.0199))
    assert rig.hw.drive_v == 3.0
    frames = rig.until(t_last + 0.020)
    assert rig.fw.state is RigState.FAULT
    assert rig.hw.drive_v == 0.0
    beat = [rig.icd.parse_heartbeat(d) for i, d in frames if i == RIG_HEARTBEAT_ID]
    assert beat[-1].state is RigState.FAULT and beat[-1].fault_code is FaultCode.WATCHDOG
    # RUN while FAULT: answered, but the drive stays at 0 V and the flags say why
    reply = rig.feedback(rig.send(Mode.RUN, 3.0))
    assert reply.watchdog_tripped and not reply.amp_enabled
    assert rig.hw.drive_v == 0.0
    # SAFE re-arms
    frames = rig.send(Mode.SAFE)
    assert rig.states(frames) == [RigState.READY]
    reply = rig.feedback(rig.send(Mode.RUN, 3.0))
    assert reply.amp_enabled and not reply.watchdog_tripped
    assert rig.hw.drive_v == 3.0
    assert rig.fw.counters.watchdog_trips == 1


def test_watchdog_is_not_armed_while_ready(rig: Harness) -> None:
    ready(rig)
    rig.send(Mode.SAFE)
    rig.until(5.0)
    assert rig.fw.state is RigState.READY


def test_safe_while_running_returns_to_ready_with_zero_drive(rig: Harness) -> None:
    ready(rig)
    rig.send(Mode.RUN, 3.0)
    frames = rig.send(Mode.SAFE)
    assert rig.states(frames) == [RigState.READY]
    assert rig.hw.drive_v == 0.0
    assert not rig.feedback(frames).amp_enabled


@pytest.mark.parametrize(
    ("attribute", "value", "flag", "code"),
    [
        ("current_a", 9.0, "over_current", FaultCode.OVER_CURRENT),
        ("current_a", -9.0, "over_current", FaultCode.OVER_CURRENT),
        ("current_a", math.nan, "over_current", FaultCode.OVER_CURRENT),
        ("position_mm", 19.8, "travel_limit", FaultCode.TRAVEL_LIMIT),
        ("position_mm", -0.8, "travel_limit", FaultCode.TRAVEL_LIMIT),
        ("position_mm", 25.0, "lvdt_fault", FaultCode.LVDT_FAULT),
        ("position_mm", math.nan, "lvdt_fault", FaultCode.LVDT_FAULT),
        ("supply_v", 12.0, None, FaultCode.SUPPLY_LOW),
    ],
)
def test_trips_latch_fault_with_zero_drive(rig: Harness, attribute: str, value: float, flag: str | None,
                                           code: FaultCode) -> None:
    ready(rig)
    rig.send(Mode.RUN, 3.0)
    setattr(rig.hw, attribute, value)
    frames = rig.send(Mode.RUN, 3.0)
    reply = rig.feedback(frames)
    assert rig.hw.drive_v == 0.0
    assert rig.fw.state is RigState.FAULT and rig.fw.fault_code is code
    assert not reply.amp_enabled
    if flag is not None:
        assert getattr(reply, flag)
    assert math.isfinite(reply.position_mm) and math.isfinite(reply.current_a)
    # still latched after the cause goes away, until SAFE
    setattr(rig.hw, attribute, FakeHardware().__dict__[attribute])
    assert not rig.feedback(rig.send(Mode.RUN, 3.0)).amp_enabled
    rig.send(Mode.SAFE)
    assert rig.fw.state is RigState.READY and rig.fw.fault_code is FaultCode.NONE
    assert rig.feedback(rig.send(Mode.RUN, 3.0)).amp_enabled


def test_other_ids_are_ignored(rig: Harness, icd: Icd) -> None:
    ready(rig)
    assert rig.fw.on_frame(0x121, icd.make_bench_cmd(1, Mode.RUN, 3.0, 10.0), rig.t) == []
    assert rig.hw.drive_v == 0.0


def _with_mode(icd: Icd, counter: int, mode: int, drive_v: float) -> bytes:
    """A BENCH_CMD payload with any Mode byte and a correct CRC (make_bench_cmd keeps to the DBC's 0..1)."""
    payload = bytearray(icd.make_bench_cmd(counter, Mode.RUN, drive_v, 10.0))
    payload[2] = mode
    payload[0] = e2e_crc(icd.bench_cmd_data_id, bytes(payload))
    return bytes(payload)


@pytest.mark.parametrize("mode", [2, 3, 0x80, 255])
def test_undefined_mode_is_ignored_and_counted_like_a_bad_crc(rig: Harness, icd: Icd, mode: int) -> None:
    ready(rig)
    assert rig.send(Mode.RUN, payload=_with_mode(icd, 1, mode, 3.0)) == []  # READY: not obeyed as RUN
    assert rig.hw.drive_v == 0.0 and rig.fw.state is RigState.READY
    rig.feedback(rig.send(Mode.RUN, 1.0, counter=1))  # its counter was not taken either
    assert rig.send(Mode.RUN, payload=_with_mode(icd, 2, mode, 3.0)) == []  # RUNNING: no reply, drive kept
    assert rig.hw.drive_v == 1.0
    assert rig.fw.counters.bad_mode == 2 and rig.fw.counters.accepted == 1
    assert rig.fw.next_deadline_s() == pytest.approx(rig.t + LIMITS.watchdog_s)  # it does not feed the watchdog


@pytest.mark.parametrize("dlc", [0, 1, 7, 9])
def test_bench_cmd_of_another_length_is_ignored_and_counted(rig: Harness, icd: Icd, dlc: int) -> None:
    ready(rig)
    payload = (icd.make_bench_cmd(1, Mode.RUN, 3.0, 10.0) + b"\x00")[:dlc]
    assert rig.send(Mode.RUN, payload=payload) == []
    assert rig.hw.drive_v == 0.0 and rig.fw.counters.bad_length == 1 and rig.fw.counters.accepted == 0


def test_a_stalled_main_loop_sends_one_heartbeat_and_keeps_its_grid(rig: Harness) -> None:
    ready(rig)  # beats due up to 0.2 s sent
    rig.fw.skip_missed_heartbeats(1.05)  # held up from 0.25 s to 1.05 s: beats at 0.3 ... 1.0 missed
    assert rig.states(rig.until(1.05)) == [RigState.READY]  # one, not eight
    assert rig.fw.next_deadline_s() == pytest.approx(1.1)
    rig.fw.skip_missed_heartbeats(1.1)  # nothing missed: nothing changes
    assert len(rig.states(rig.until(1.1))) == 1
    assert rig.fw.next_deadline_s() == pytest.approx(1.2)
