"""Rig firmware prototype: the rig side of ICD v1 as a state machine.

Pure logic: frames in, frames out, time passed in explicitly. The hardware
(LVDT, current sensor, drive amplifier) sits behind :class:`RigHardware`, so
the same logic runs over the simulated plant and could run over real I/O.
See ``PROTOCOL.md`` beside this file for the rules it implements. It builds
on :mod:`edc_bench.protocol` alone (the ICD, its codec and its errors), nothing
else from edc-bench.

States: BOOT -> READY after ``boot_s``; READY -> RUNNING on a valid RUN
command; RUNNING -> READY on a valid SAFE command; any -> FAULT on a trip
(watchdog, over-current, LVDT fault, travel limit, supply low), latched with
the drive at 0 V until a valid SAFE command re-arms the rig.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Protocol


from edc_bench.protocol import (
    BENCH_CMD_ID,
    RIG_FEEDBACK_ID,
    RIG_HEARTBEAT_ID,
    E2EError,
    FaultCode,
    Icd,
    Mode,
    ProtocolError,
    RigState,
    default_icd,
)

FW_MAJOR = 1
FW_MINOR = 0
#: the Mode values the ICD defines (DBC: 0 SAFE, 1 RUN); any other is an invalid frame, never a command
DEFINED_MODES = frozenset(int(mode) for mode in Mode)

Frame = tuple[int, bytes]
"""An outgoing CAN frame: (arbitration id, payload)."""


class RigHardware(Protocol):
    """What the firmware needs from the rig's hardware."""

    def sample_position_mm(self) -> float:
        """Sample the LVDT rack position (NaN if the LVDT reads nothing)."""
        ...

    def sample_current_a(self) -> float:
        """Sample the coil current."""
        ...

    def set_drive_v(self, drive_v: float) -> None:
        """Set the amplifier's drive voltage (0 V is the safe state)."""
        ...

    def supply_voltage_v(self) -> float:
        """Read the amplifier supply voltage."""
        ...


@dataclass(frozen=True)
class FirmwareLimits:
    """Limits and timing of the rig firmware.

    Attributes
    ----------
    drive_limit_v : float
        Commanded drive is clamped to +/- this.
    over_current_a : float
        A coil current sample beyond +/- this trips OVER_CURRENT.
    travel_min_mm, travel_max_mm : float
        A rack sample outside trips TRAVEL_LIMIT.
    lvdt_min_mm, lvdt_max_mm : float
        A rack sample outside (or NaN) is an LVDT fault.
    supply_min_v : float
        A supply below this trips SUPPLY_LOW.
    watchdog_s, heartbeat_period_s, boot_s : float
        Watchdog time, heartbeat period, time spent in BOOT.
    """

    drive_limit_v: float = 24.0
    over_current_a: float = 15.0
    travel_min_mm: float = 0.0
    travel_max_mm: float = 19.5
    lvdt_min_mm: float = -1.0
    lvdt_max_mm: float = 30.0
    supply_min_v: float = 18.0
    watchdog_s: float = 0.020
    heartbeat_period_s: float = 0.100
    boot_s: float = 0.200


@dataclass
class FirmwareCounters:
    """Counters a rig keeps for diagnosis."""

    accepted: int = 0
    bad_crc: int = 0
    bad_length: int = 0
    bad_mode: int = 0
    repeated_counter: int = 0
    stale_counter: int = 0
    ignored_in_boot: int = 0
    watchdog_trips: int = 0
    faults: dict[str, int] = field(default_factory=dict)


class RigFirmware:
    """The rig's ICD logic.

    Parameters
    ----------
    hardware : RigHardware
        Sensors and amplifier.
    limits : FirmwareLimits
        Limits and timing.
    start_s : float, optional
        Time at power-up, in the caller's time base.
    icd : Icd, optional
        The compiled ICD (the packaged one by default).
    """

    def __init__(self, hardware: RigHardware, limits: FirmwareLimits, start_s: float = 0.0,
                 icd: Icd | None = None) -> None:
        self.hw = hardware
        self.limits = limits
        self.icd = icd or default_icd()
        self.state = RigState.BOOT
        self.fault_code = FaultCode.NONE
        self.flags = {"watchdog": False, "over_current": False, "lvdt": False, "travel": False}
        self.counters = FirmwareCounters()
        self._last_counter: int | None = None
        self._boot_done_s = start_s + limits.boot_s
        self._next_heartbeat_s = start_s
        self._watchdog_due_s = math.inf
        self.heartbeat_enabled = True  # fault injection: a rig whose heartbeat stops
        self.hw.set_drive_v(0.0)

    # -- time ------------------------------------------------------------------
    def next_deadline_s(self) -> float:
        """Earliest time at which :meth:`on_time` has something to do."""
        deadline = min(self._next_heartbeat_s, self._watchdog_due_s)
        if self.state is RigState.BOOT:
            deadline = min(deadline, self._boot_done_s)
        return deadline

    def on_time(self, now_s: float) -> list[Frame]:
        """Run the timers due at ``now_s``: boot, watchdog, heartbeat.

        Returns
        -------
        list of (int, bytes)
            Frames to send (heartbeats).
        """
        out: list[Frame] = []
        if self.state is RigState.BOOT and now_s >= self._boot_done_s:
            self._enter(RigState.READY, out)
        if now_s >= self._watchdog_due_s:
            self._watchdog_due_s = math.inf
            self.counters.watchdog_trips += 1
            self.flags["watchdog"] = True
            self._trip(FaultCode.WATCHDOG, out)
        if now_s >= self._next_heartbeat_s:
            if self.heartbeat_enabled:
                out.append(self._heartbeat())
            # keep the 10 Hz grid; skip missed beats rather than bursting them
            self._next_heartbeat_s = self._heartbeat_after(now_s)
        return out

    def skip_missed_heartbeats(self, now_s: float) -> None:
        """Tell the firmware its main loop was held up until ``now_s``.

        A caller that runs the timers deadline by deadline (the simulated rig
        catching up on lost time) would otherwise send every periodic
        heartbeat missed meanwhile in one burst. After this, at most one is
        still due by ``now_s`` (the latest on the grid), and the next one
        after it falls on the grid again. Other timers are untouched: the
        watchdog still trips when it was due.

        Parameters
        ----------
        now_s : float
            The time the main loop resumes.
        """
        if now_s >= self._next_heartbeat_s + self.limits.heartbeat_period_s:
            self._next_heartbeat_s = self._heartbeat_after(now_s) - self.limits.heartbeat_period_s

    def _heartbeat_after(self, now_s: float) -> float:
        """The first heartbeat time on the grid from power-up later than ``now_s``."""
        period = self.limits.heartbeat_period_s
        missed = math.floor((now_s - self._next_heartbeat_s) / period)
        return self._next_heartbeat_s + (missed + 1) * period

    # -- frames ----------------------------------------------------------------
    def on_frame(self, can_id: int, data: bytes | bytearray, now_s: float) -> list[Frame]:
        """Handle one received frame.

        Parameters
        ----------
        can_id : int
            Arbitration id.
        data : bytes
            Payload.
        now_s : float
            Reception time.

        Returns
        -------
        list of (int, bytes)
            Frames to send: a ``RIG_FEEDBACK`` for a valid ``BENCH_CMD`` and
            a heartbeat if the state changed; nothing for anything else.
        """
        if can_id != BENCH_CMD_ID:
            return []
        try:
            cmd = self.icd.parse_bench_cmd(data)
        except E2EError:
            self.counters.bad_crc += 1
            return []
        except ProtocolError:
            self.counters.bad_length += 1
            return []
        if cmd.mode not in DEFINED_MODES:  # the ICD defines SAFE and RUN only: any other Mode is an invalid frame
            self.counters.bad_mode += 1
            return []
        if self.state is RigState.BOOT:
            self.counters.ignored_in_boot += 1
            return []
        if not self._counter_is_new(cmd.counter, cmd.mode):
            return []
        self.counters.accepted += 1
        out: list[Frame] = []

        # Samples are taken before the new drive is applied (ICD 3.1).
        position_mm = self.hw.sample_position_mm()
        current_a = self.hw.sample_current_a()
        self._check_samples(position_mm, current_a, out)

        if cmd.mode == Mode.SAFE:
            self.hw.set_drive_v(0.0)
            self._watchdog_due_s = math.inf
            if self.state is RigState.FAULT:
                for key in self.flags:
                    self.flags[key] = False
                self.fault_code = FaultCode.NONE
            if self.state is not RigState.READY:
                self._enter(RigState.READY, out)
        elif cmd.mode == Mode.RUN and self.state is not RigState.FAULT:
            limit = self.limits.drive_limit_v
            drive_v = max(-limit, min(limit, cmd.drive_v))
            self.hw.set_drive_v(drive_v)
            self._watchdog_due_s = now_s + self.limits.watchdog_s
            if self.state is RigState.READY:
                self._enter(RigState.RUNNING, out)
        # RUN while FAULT: the drive stays at 0 V; the reply shows why.

        out.insert(0, (RIG_FEEDBACK_ID, self._feedback(cmd.counter, position_mm, current_a)))
        return out

    def _counter_is_new(self, counter: int, mode: int) -> bool:
        last = self._last_counter
        if last is not None:
            delta = (counter - last) % 256
            if delta == 0:
                self.counters.repeated_counter += 1
                return False
            # While the amplifier is off, a SAFE command may resynchronise the
            # counter (a new bench session starts its own count).
            if delta >= 128 and not (mode == Mode.SAFE and self.state is not RigState.RUNNING):
                self.counters.stale_counter += 1
                return False
        self._last_counter = counter
        return True

    def _check_samples(self, position_mm: float, current_a: float, out: list[Frame]) -> None:
        lim = self.limits
        if not (lim.lvdt_min_mm <= position_mm <= lim.lvdt_max_mm):  # also catches NaN
            self.flags["lvdt"] = True
            self._trip(FaultCode.LVDT_FAULT, out)
        elif not (lim.travel_min_mm <= position_mm <= lim.travel_max_mm):
            self.flags["travel"] = True
            self._trip(FaultCode.TRAVEL_LIMIT, out)
        if not abs(current_a) <= lim.over_current_a:  # also catches NaN
            self.flags["over_current"] = True
            self._trip(FaultCode.OVER_CURRENT, out)
        if self.hw.supply_voltage_v() < lim.supply_min_v:
            self._trip(FaultCode.SUPPLY_LOW, out)

    def _trip(self, code: FaultCode, out: list[Frame]) -> None:
        self.hw.set_drive_v(0.0)
        self._watchdog_due_s = math.inf
        self.counters.faults[code.name] = self.counters.faults.get(code.name, 0) + 1
        if self.fault_code is FaultCode.NONE:
            self.fault_code = code  # the first cause is the one reported
        if self.state is not RigState.FAULT:
            self._enter(RigState.FAULT, out)

    def force_fault(self, code: FaultCode) -> list[Frame]:
        """Latch a fault from outside the protocol (a hardware monitor, or a test)."""
        out: list[Frame] = []
        self._trip(code, out)
        return out

    def _enter(self, state: RigState, out: list[Frame]) -> None:
        self.state = state
        if self.heartbeat_enabled:
            out.append(self._heartbeat())  # a state change is announced at once

    def _heartbeat(self) -> Frame:
        supply_v = min(max(self.hw.supply_voltage_v(), 0.0), 655.35)
        return (RIG_HEARTBEAT_ID, self.icd.make_heartbeat(self.state, self.fault_code, FW_MAJOR, FW_MINOR, supply_v))

    def _feedback(self, counter: int, position_mm: float, current_a: float) -> bytes:
        f = self.flags
        # Out-of-range samples are clamped to what the frame can carry; the
        # fault flags say they were not valid.
        position_mm = 0.0 if position_mm != position_mm else min(max(position_mm, 0.0), 65.535)
        current_a = 0.0 if current_a != current_a else min(max(current_a, -32.768), 32.767)
        return self.icd.make_rig_feedback(
            counter,
            amp_enabled=self.state is RigState.RUNNING,
            watchdog_tripped=f["watchdog"],
            over_current=f["over_current"],
            lvdt_fault=f["lvdt"],
            travel_limit=f["travel"],
            position_mm=position_mm,
            current_a=current_a,
        )
