"""ICD v1 frames as typed values: make bytes, parse bytes, no I/O.

All layouts, ids and E2E data ids come from the DBC beside this module
(``icd_v1.dbc``, see :func:`dbc_path`); nothing about the wire format is
written here twice. ``make_*`` functions return payload bytes (with the CRC
filled in where the ICD asks for one); ``parse_*`` functions check length and
CRC and return a named tuple.
"""

from __future__ import annotations

import enum
from collections.abc import Callable
from functools import lru_cache
from importlib import resources
from operator import itemgetter
from pathlib import Path
from typing import Any, NamedTuple

from edc_bench.protocol.crc import e2e_crc
from edc_bench.protocol.errors import E2EError, ProtocolError
from edc_bench.protocol.layout import MessageLayout, compile_message

DBC_FILENAME = "icd_v1.dbc"

BENCH_CMD_ID = 0x120
RIG_FEEDBACK_ID = 0x121
RIG_HEARTBEAT_ID = 0x720


def dbc_path() -> Path:
    """Return the path of the ICD v1 DBC file, the single source of truth.

    The DBC ships inside this package, so it is found the same way from a
    source checkout and from a non-editable install.

    Returns
    -------
    pathlib.Path
        Path of ``icd_v1.dbc`` inside the installed ``edc_bench.protocol`` package.
    """
    return Path(str(resources.files(__package__).joinpath(DBC_FILENAME)))


class Mode(enum.IntEnum):
    """``BENCH_CMD.Mode``."""

    SAFE = 0
    RUN = 1


class RigState(enum.IntEnum):
    """``RIG_HEARTBEAT.State``."""

    BOOT = 0
    READY = 1
    RUNNING = 2
    FAULT = 3


class FaultCode(enum.IntEnum):
    """``RIG_HEARTBEAT.FaultCode``: why the rig latched FAULT."""

    NONE = 0
    WATCHDOG = 1
    OVER_CURRENT = 2
    LVDT_FAULT = 3
    TRAVEL_LIMIT = 4
    SUPPLY_LOW = 5


class BenchCmd(NamedTuple):
    """Decoded ``BENCH_CMD``."""

    counter: int
    mode: int
    drive_v: float
    reference_mm: float


class RigFeedback(NamedTuple):
    """Decoded ``RIG_FEEDBACK``."""

    counter: int
    amp_enabled: bool
    watchdog_tripped: bool
    over_current: bool
    lvdt_fault: bool
    travel_limit: bool
    position_mm: float
    current_a: float

    @property
    def any_fault(self) -> bool:
        """True if any fault flag is set."""
        return self.watchdog_tripped or self.over_current or self.lvdt_fault or self.travel_limit


class RigHeartbeat(NamedTuple):
    """Decoded ``RIG_HEARTBEAT``."""

    state: RigState
    fault_code: FaultCode
    fw_major: int
    fw_minor: int
    supply_v: float


# Each typed frame's fields and the DBC signal each carries (the names are fixed: firmware_proto/PROTOCOL.md).
BENCH_CMD_SIGNALS = {"counter": "Counter", "mode": "Mode", "drive_v": "DriveVoltage", "reference_mm": "RackReference"}
RIG_FEEDBACK_SIGNALS = {
    "counter": "Counter", "amp_enabled": "AmpEnabled", "watchdog_tripped": "WatchdogTripped",
    "over_current": "OverCurrent", "lvdt_fault": "LvdtFault", "travel_limit": "TravelLimit",
    "position_mm": "RackPosition", "current_a": "CoilCurrent",
}
RIG_HEARTBEAT_SIGNALS = {"state": "State", "fault_code": "FaultCode", "fw_major": "FwMajor", "fw_minor": "FwMinor",
                         "supply_v": "SupplyVoltage"}


def _by_name(layout: MessageLayout, signals: dict[str, str], fields: tuple[str, ...]) -> Callable[[tuple], tuple]:
    """A picker from the layout's decoded values (DBC order) to the typed frame's fields, chosen by signal name."""
    if tuple(signals) != fields:
        raise ProtocolError(f"{layout.name}: the field map does not match {fields}")
    names = layout.signal_names
    missing = [s for s in signals.values() if s not in names]
    if missing:
        raise ProtocolError(f"{layout.name}: the DBC lacks signal(s) {', '.join(missing)} (have {', '.join(names)})")
    return itemgetter(*(names.index(s) for s in signals.values()))


class Icd:
    """The compiled ICD: one layout per message, read from the DBC once.

    Parameters
    ----------
    dbc_file : pathlib.Path, optional
        DBC to load; the packaged ICD v1 by default.
    """

    def __init__(self, dbc_file: Path | None = None) -> None:
        import cantools  # deferred: only needed once, at start-up

        self.dbc_file = Path(dbc_file) if dbc_file is not None else dbc_path()
        database = cantools.database.load_file(str(self.dbc_file))
        if not isinstance(database, cantools.database.can.Database) or database.dbc is None:
            raise ProtocolError(f"{self.dbc_file}: not a CAN database in DBC format")
        self.database = database
        self._dbc = database.dbc
        self.bench_cmd = self._layout("BENCH_CMD", BENCH_CMD_ID)
        self.rig_feedback = self._layout("RIG_FEEDBACK", RIG_FEEDBACK_ID)
        self.rig_heartbeat = self._layout("RIG_HEARTBEAT", RIG_HEARTBEAT_ID)
        self._bench_cmd_fields = _by_name(self.bench_cmd, BENCH_CMD_SIGNALS, BenchCmd._fields)
        self._rig_feedback_fields = _by_name(self.rig_feedback, RIG_FEEDBACK_SIGNALS, RigFeedback._fields)
        self._heartbeat_fields = _by_name(self.rig_heartbeat, RIG_HEARTBEAT_SIGNALS, RigHeartbeat._fields)
        # encoding takes the typed values in the DBC's order: hold the DBC to the typed frames' order by name
        for layout, signals in ((self.bench_cmd, BENCH_CMD_SIGNALS), (self.rig_feedback, RIG_FEEDBACK_SIGNALS),
                                (self.rig_heartbeat, RIG_HEARTBEAT_SIGNALS)):
            expected = tuple(signals.values())
            if tuple(n for n in layout.signal_names if n != "CRC") != expected:
                raise ProtocolError(f"{self.dbc_file}: {layout.name} signals {layout.signal_names} are not in the "
                                    f"ICD v1 order {expected}")
        self.bench_cmd_data_id = self._data_id("BENCH_CMD")
        self.rig_feedback_data_id = self._data_id("RIG_FEEDBACK")
        attributes = self._dbc.attributes
        self.watchdog_ms = int(attributes["WatchdogMs"].value)
        self.bitrate = int(attributes["Baudrate"].value)
        self.version = (int(attributes["IcdVersionMajor"].value), int(attributes["IcdVersionMinor"].value))

    def _layout(self, name: str, expected_id: int) -> MessageLayout:
        message = self.database.get_message_by_name(name)
        if message.frame_id != expected_id:
            raise ProtocolError(
                f"{self.dbc_file}: message {name} has id {message.frame_id:#x}, ICD v1 fixes {expected_id:#x}"
            )
        return compile_message(message)

    def _data_id(self, name: str) -> int:
        message = self.database.get_message_by_name(name)
        attribute = message.dbc.attributes.get("E2EDataId") if message.dbc else None
        if attribute is None:
            raise ProtocolError(f"{self.dbc_file}: message {name} has no E2EDataId attribute")
        return int(attribute.value)

    # -- E2E -------------------------------------------------------------------
    @staticmethod
    def _e2e_encode(layout: MessageLayout, data_id: int, *values: float) -> bytes:
        """Encode with CRC 0, then put the CRC over data id and bytes 1..7 in byte 0."""
        body = layout.encode(0, *values)
        return bytes((e2e_crc(data_id, body),)) + body[1:]

    @staticmethod
    def _e2e_decode(layout: MessageLayout, data_id: int, payload: bytes | bytearray) -> tuple:
        """Decode and check the CRC; raises E2EError on a mismatch."""
        values = layout.decode(payload)
        if values[0] != e2e_crc(data_id, payload):
            raise E2EError(f"{layout.name} CRC mismatch: got {values[0]:#04x}")
        return values

    # -- BENCH_CMD -----------------------------------------------------------
    def make_bench_cmd(self, counter: int, mode: int, drive_v: float, reference_mm: float) -> bytes:
        """Payload of a ``BENCH_CMD`` with its CRC.

        Parameters
        ----------
        counter : int
            Rolling counter, 0..255.
        mode : int
            :class:`Mode` value.
        drive_v : float
            Drive voltage in V (-32.768..32.767).
        reference_mm : float
            Rack reference in mm (0..65.535).

        Returns
        -------
        bytes
            The 8 payload bytes.
        """
        return self._e2e_encode(self.bench_cmd, self.bench_cmd_data_id, counter, mode, drive_v, reference_mm)

    def parse_bench_cmd(self, payload: bytes | bytearray) -> BenchCmd:
        """Check and decode a ``BENCH_CMD`` payload.

        Raises
        ------
        E2EError
            If the CRC does not match.
        ProtocolError
            If the payload has the wrong length.
        """
        return BenchCmd._make(self._bench_cmd_fields(self._e2e_decode(self.bench_cmd, self.bench_cmd_data_id,
                                                                        payload)))

    # -- RIG_FEEDBACK --------------------------------------------------------
    def make_rig_feedback(
        self,
        counter: int,
        *,
        amp_enabled: bool,
        watchdog_tripped: bool,
        over_current: bool,
        lvdt_fault: bool,
        travel_limit: bool,
        position_mm: float,
        current_a: float,
    ) -> bytes:
        """Payload of a ``RIG_FEEDBACK`` with its CRC."""
        return self._e2e_encode(
            self.rig_feedback, self.rig_feedback_data_id, counter, amp_enabled, watchdog_tripped, over_current,
            lvdt_fault, travel_limit, position_mm, current_a,
        )

    def parse_rig_feedback(self, payload: bytes | bytearray) -> RigFeedback:
        """Check and decode a ``RIG_FEEDBACK`` payload.

        Raises
        ------
        E2EError
            If the CRC does not match.
        ProtocolError
            If the payload has the wrong length.
        """
        counter, amp, watchdog, over_current, lvdt, travel, position_mm, current_a = self._rig_feedback_fields(
            self._e2e_decode(self.rig_feedback, self.rig_feedback_data_id, payload))
        return RigFeedback(counter, bool(amp), bool(watchdog), bool(over_current), bool(lvdt), bool(travel),
                           position_mm, current_a)

    # -- RIG_HEARTBEAT -------------------------------------------------------
    def make_heartbeat(self, state: RigState, fault_code: FaultCode, fw_major: int, fw_minor: int,
                       supply_v: float) -> bytes:
        """Payload of a ``RIG_HEARTBEAT`` (no E2E protection in ICD v1)."""
        return self.rig_heartbeat.encode(int(state), int(fault_code), fw_major, fw_minor, supply_v)

    def parse_heartbeat(self, payload: bytes | bytearray) -> RigHeartbeat:
        """Decode a ``RIG_HEARTBEAT`` payload.

        Raises
        ------
        ProtocolError
            If the payload has the wrong length or an unknown state or fault code.
        """
        state, fault_code, fw_major, fw_minor, supply_v = self._heartbeat_fields(self.rig_heartbeat.decode(payload))
        try:
            return RigHeartbeat(RigState(state), FaultCode(fault_code), fw_major, fw_minor, supply_v)
        except ValueError as exc:
            raise ProtocolError(f"RIG_HEARTBEAT: {exc}") from None

    def choices(self, message: str, signal: str) -> dict[int, str]:
        """Value table of a signal as written in the DBC (for checks and display)."""
        sig: Any = self.database.get_message_by_name(message).get_signal_by_name(signal)
        return {int(k): str(v) for k, v in (sig.choices or {}).items()}


@lru_cache(maxsize=1)
def default_icd() -> Icd:
    """The packaged ICD v1, loaded once per process."""
    return Icd()
