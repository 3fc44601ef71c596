"""Rigs that each break one ICD v1 rule: what ``edc-bench rig-check`` must catch.

A rig builder's firmware can go wrong in ways the bench would not notice in a
test (it would measure, judge, and blame the valve). Each :class:`IcdBreak`
is one such mistake, built as the simulated rig's firmware with that one
rule broken, so the conformance suite can be shown to name it
(``tests/rigcheck``) and a rig builder can see what a NO-GO looks like
(``edc-bench rig --break RULE``). The firmware prototype itself stays the
reference: these are subclasses here, not options in it.
"""

from __future__ import annotations

import enum
import math
from collections.abc import Callable, Iterable
from dataclasses import replace

from edc_bench.protocol import BENCH_CMD_ID, RIG_FEEDBACK_ID, BenchCmd, E2EError, Mode, ProtocolError, RigState
from edc_bench.protocol.crc import e2e_crc
from firmware_proto.firmware import FirmwareLimits, Frame, RigFirmware, RigHardware


class IcdBreak(enum.Enum):
    """One ICD v1 rule a rig breaks (its value is the name ``--break`` takes)."""

    ANSWERS_BAD_CRC = "answers-bad-crc"  # takes a BENCH_CMD whose CRC is wrong as valid
    WRONG_COUNTER_ECHO = "wrong-counter-echo"  # RIG_FEEDBACK carries the command's counter plus one
    SLOW_WATCHDOG = "slow-watchdog"  # trips 60 ms after the last command, not 20
    NO_WATCHDOG = "no-watchdog"  # never trips: keeps the last drive when the bench falls silent
    NO_HEARTBEAT = "no-heartbeat"  # sends no RIG_HEARTBEAT at all
    SLOW_HEARTBEAT = "slow-heartbeat"  # a heartbeat every 300 ms, not 100
    DRIVES_AFTER_SAFE = "drives-after-safe"  # reports READY after SAFE but keeps the last RUN drive
    SAMPLES_AFTER_DRIVE = "samples-after-drive"  # samples half a millisecond after applying the new drive

    @classmethod
    def parse(cls, text: str) -> IcdBreak:
        """The break named ``text``; ValueError naming the choices otherwise."""
        for rule in cls:
            if rule.value == text:
                return rule
        raise ValueError(f"no such ICD break {text!r}: one of {', '.join(rule.value for rule in cls)}")


#: How late the SAMPLES_AFTER_DRIVE rig takes its samples after applying the drive.
LATE_SAMPLE_S = 0.0005


def broken_limits(limits: FirmwareLimits, breaks: Iterable[IcdBreak]) -> FirmwareLimits:
    """The firmware limits of a rig with ``breaks`` (the timing ones are limits)."""
    breaks = set(breaks)
    if IcdBreak.SLOW_WATCHDOG in breaks:
        limits = replace(limits, watchdog_s=3.0 * limits.watchdog_s)
    if IcdBreak.NO_WATCHDOG in breaks:
        limits = replace(limits, watchdog_s=math.inf)
    if IcdBreak.SLOW_HEARTBEAT in breaks:
        limits = replace(limits, heartbeat_period_s=3.0 * limits.heartbeat_period_s)
    return limits


class BrokenFirmware(RigFirmware):
    """The firmware prototype with some ICD rules broken.

    Parameters
    ----------
    hardware, limits, start_s
        As :class:`~firmware_proto.firmware.RigFirmware` (``limits`` as the rig should have them).
    breaks : iterable of IcdBreak
        The rules it breaks.
    let_time_pass : callable, optional
        ``let_time_pass(dt_s)`` moves the plant on (SAMPLES_AFTER_DRIVE needs it).
    """

    def __init__(self, hardware: RigHardware, limits: FirmwareLimits, start_s: float, breaks: Iterable[IcdBreak],
                 let_time_pass: Callable[[float], None] | None = None) -> None:
        self.breaks = frozenset(breaks)
        super().__init__(hardware, broken_limits(limits, self.breaks), start_s)
        self.heartbeat_enabled = IcdBreak.NO_HEARTBEAT not in self.breaks
        self._let_time_pass = let_time_pass
        self._run_drive_v = 0.0

    def on_frame(self, can_id: int, data: bytes | bytearray, now_s: float) -> list[Frame]:
        """As the prototype's, with the rules broken."""
        if can_id != BENCH_CMD_ID:
            return []
        data = bytes(data)
        if IcdBreak.ANSWERS_BAD_CRC in self.breaks and len(data) == 8:
            data = bytes((e2e_crc(self.icd.bench_cmd_data_id, data),)) + data[1:]  # whatever came, as if valid
        cmd = self._command(data)
        if cmd is not None and IcdBreak.SAMPLES_AFTER_DRIVE in self.breaks and cmd.mode == Mode.RUN \
                and self.state in (RigState.READY, RigState.RUNNING) and self._let_time_pass is not None:
            limit = self.limits.drive_limit_v
            self.hw.set_drive_v(max(-limit, min(limit, cmd.drive_v)))
            self._let_time_pass(LATE_SAMPLE_S)  # the base then samples, late, and applies the same drive
        out = super().on_frame(can_id, data, now_s)
        if cmd is None or not out or out[0][0] != RIG_FEEDBACK_ID:
            return out
        if cmd.mode == Mode.RUN and self.state is RigState.RUNNING:
            self._run_drive_v = cmd.drive_v
        if cmd.mode == Mode.SAFE and IcdBreak.DRIVES_AFTER_SAFE in self.breaks:
            self.hw.set_drive_v(self._run_drive_v)
        if IcdBreak.WRONG_COUNTER_ECHO in self.breaks:
            reply = bytearray(out[0][1])
            reply[1] = (reply[1] + 1) % 256
            reply[0] = e2e_crc(self.icd.rig_feedback_data_id, reply)
            out[0] = (RIG_FEEDBACK_ID, bytes(reply))
        return out

    def _command(self, data: bytes) -> BenchCmd | None:
        """The command, if the frame is one (whatever the state and counter)."""
        try:
            return self.icd.parse_bench_cmd(data)
        except (E2EError, ProtocolError):
            return None


__all__ = ["LATE_SAMPLE_S", "BrokenFirmware", "IcdBreak", "broken_limits"]
