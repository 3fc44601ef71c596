"""Frames to and from a rig under test, timed by the bench's clock.

The conformance checks talk to the rig the way the bench does: a python-can
bus and a :class:`~edc_bench.runtime.clock.Clock` (real time on a rig; the
simulated clock stepping an in-process rig in the tests). Every frame the rig
sends is kept with the time it was received, so each check can look back at
what came in answer to what it sent.
"""

from __future__ import annotations

from dataclasses import dataclass

from edc_bench.canlib import can
from edc_bench.protocol import (
    BENCH_CMD_ID,
    RIG_FEEDBACK_ID,
    RIG_HEARTBEAT_ID,
    E2EError,
    Icd,
    Mode,
    ProtocolError,
    RigFeedback,
    RigHeartbeat,
)
from edc_bench.protocol.crc import e2e_crc
from edc_bench.runtime.clock import Clock

#: How finely a wait looks at the bus (the resolution of every time a check measures).
STEP_S = 0.0005


@dataclass(frozen=True)
class Received:
    """A frame from the rig and when it came (s on the session's clock)."""

    t_s: float
    can_id: int
    data: bytes


@dataclass(frozen=True)
class Sent:
    """A BENCH_CMD the session sent: its counter, mode, drive and time."""

    t_s: float
    counter: int
    mode: int
    drive_v: float


class RigSession:
    """A conversation with one rig.

    Parameters
    ----------
    bus : can.BusABC
        The bench's end of the bus.
    clock : Clock
        Started by the session; its time stamps every frame.
    icd : Icd
        The compiled ICD.
    """

    def __init__(self, bus: can.BusABC, clock: Clock, icd: Icd) -> None:
        self.bus, self.clock, self.icd = bus, clock, icd
        self.received: list[Received] = []
        self.counter = 0
        self.worst_late_s = 0.0  # the latest the clock woke the session: a machine that did not run it
        clock.start()

    def now_s(self) -> float:
        """The session's time."""
        return self.clock.now_s()

    def send_raw(self, can_id: int, data: bytes) -> float:
        """Send any frame; its time."""
        t_s = self.clock.now_s()
        self.bus.send(can.Message(arbitration_id=can_id, data=data, is_extended_id=False))
        self.clock.after_send(t_s)
        return t_s

    def command(self, mode: Mode | int, drive_v: float = 0.0, *, counter: int | None = None, bad_crc: bool = False,
                length: int = 8) -> Sent:
        """Send a BENCH_CMD (the next counter unless given); ``bad_crc``, ``length`` or a ``mode`` the ICD does not
        define make it invalid."""
        if counter is None:
            self.counter = (self.counter + 1) % 256
            counter = self.counter
        defined = int(mode) in (int(m) for m in Mode)
        data = bytearray(self.icd.make_bench_cmd(counter, int(mode) if defined else int(Mode.SAFE), drive_v, 0.0))
        if not defined:  # the codec refuses it: byte 2 is Mode (PROTOCOL.md), with a CRC that holds for it
            data[2] = int(mode)
            data[0] = e2e_crc(self.icd.bench_cmd_data_id, data)
        if bad_crc:
            data[0] ^= 0x5A
        return Sent(self.send_raw(BENCH_CMD_ID, bytes(data[:length])), counter, int(mode), drive_v)

    def wait_until(self, t_s: float) -> None:
        """Keep reading the bus until the session's time ``t_s``."""
        while True:
            self._drain()
            now = self.clock.now_s()
            if now >= t_s:
                return
            self.worst_late_s = max(self.worst_late_s, self.clock.wait_until(min(t_s, now + STEP_S)))

    def wait(self, dt_s: float) -> None:
        """Keep reading the bus for ``dt_s``."""
        self.wait_until(self.clock.now_s() + dt_s)

    def _drain(self) -> None:
        while True:
            msg = self.bus.recv(timeout=0.0)
            if msg is None:
                return
            if not (msg.is_extended_id or msg.is_remote_frame or msg.is_error_frame):
                self.received.append(Received(self.clock.now_s(), msg.arbitration_id, bytes(msg.data)))

    # -- what came ------------------------------------------------------------------------------------------------
    def feedback(self, since_s: float, until_s: float = float("inf")) -> list[tuple[float, RigFeedback | None]]:
        """RIG_FEEDBACK frames received in [since_s, until_s): (time, decoded or None where its CRC or length is
        wrong)."""
        out: list[tuple[float, RigFeedback | None]] = []
        for frame in self.received:
            if frame.can_id == RIG_FEEDBACK_ID and since_s <= frame.t_s < until_s:
                try:
                    out.append((frame.t_s, self.icd.parse_rig_feedback(frame.data)))
                except (E2EError, ProtocolError):
                    out.append((frame.t_s, None))
        return out

    def heartbeats(self, since_s: float, until_s: float = float("inf")) -> list[tuple[float, RigHeartbeat | None]]:
        """RIG_HEARTBEAT frames received in [since_s, until_s): (time, decoded or None where malformed)."""
        out: list[tuple[float, RigHeartbeat | None]] = []
        for frame in self.received:
            if frame.can_id == RIG_HEARTBEAT_ID and since_s <= frame.t_s < until_s:
                try:
                    out.append((frame.t_s, self.icd.parse_heartbeat(frame.data)))
                except ProtocolError:
                    out.append((frame.t_s, None))
        return out


__all__ = ["STEP_S", "Received", "RigSession", "Sent"]
