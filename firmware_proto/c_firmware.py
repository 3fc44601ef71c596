"""The C firmware core (``c/``), loaded with ctypes behind the same interface as :class:`~firmware_proto.firmware.RigFirmware`.

The simulated rig runs either firmware over the same plant (``edc-bench rig --firmware c``), and the firmware
tests run against both. The library is built by ``make -C firmware_proto/c`` (gcc and cantools); where it is
not built, :func:`load_library` says how to build it. ``EDC_BENCH_C_FIRMWARE`` names another build of it.
"""

from __future__ import annotations

import ctypes
import os
from functools import lru_cache
from pathlib import Path

from edc_bench.protocol import FaultCode, Icd, RigState, default_icd
from firmware_proto.firmware import FirmwareCounters, FirmwareLimits, Frame, RigHardware

LIBRARY_ENV = "EDC_BENCH_C_FIRMWARE"
C_DIR = Path(__file__).resolve().parent / "c"

_DOUBLE_FN = ctypes.CFUNCTYPE(ctypes.c_double, ctypes.c_void_p)
_DRIVE_FN = ctypes.CFUNCTYPE(None, ctypes.c_void_p, ctypes.c_double)
_SEND_FN = ctypes.CFUNCTYPE(None, ctypes.c_void_p, ctypes.c_uint32, ctypes.POINTER(ctypes.c_uint8), ctypes.c_uint8)


class _Hardware(ctypes.Structure):
    _fields_ = [("sample_position_mm", _DOUBLE_FN), ("sample_current_a", _DOUBLE_FN), ("set_drive_v", _DRIVE_FN),
                ("supply_voltage_v", _DOUBLE_FN), ("send", _SEND_FN), ("ctx", ctypes.c_void_p)]


class _Limits(ctypes.Structure):
    _fields_ = [(name, ctypes.c_double) for name in (
        "drive_limit_v", "over_current_a", "travel_min_mm", "travel_max_mm", "lvdt_min_mm", "lvdt_max_mm",
        "supply_min_v", "watchdog_s", "heartbeat_period_s", "boot_s")]


class CFirmwareMissing(RuntimeError):
    """The C firmware library is not built (the message says how to build it)."""


def library_path() -> Path:
    """Where the library is looked for: ``EDC_BENCH_C_FIRMWARE``, else ``c/build/libedcrig.so`` beside this file."""
    return Path(os.environ.get(LIBRARY_ENV) or C_DIR / "build" / "libedcrig.so")


def load_library(path: str | None = None) -> ctypes.CDLL:
    """The C firmware library, its functions typed.

    Raises
    ------
    CFirmwareMissing
        If it is not built: naming the command that builds it.
    """
    where = Path(path) if path else library_path()
    if not where.is_file():
        raise CFirmwareMissing(f"the C firmware is not built ({where} is missing): build it with "
                               f"'make -C {C_DIR}' (needs gcc; {LIBRARY_ENV} names a library built elsewhere)")
    return _typed(str(where))


@lru_cache(maxsize=4)
def _typed(path: str) -> ctypes.CDLL:
    """The library at ``path``, loaded once, its functions typed."""
    lib = ctypes.CDLL(path)
    fw = ctypes.c_void_p
    for name, result, args in (
            ("rig_init", None, [fw, ctypes.POINTER(_Hardware), ctypes.POINTER(_Limits), ctypes.c_double]),
            ("rig_next_deadline_s", ctypes.c_double, [fw]),
            ("rig_on_time", None, [fw, ctypes.c_double]),
            ("rig_skip_missed_heartbeats", None, [fw, ctypes.c_double]),
            ("rig_on_frame", None, [fw, ctypes.c_uint32, ctypes.c_char_p, ctypes.c_uint8, ctypes.c_double]),
            ("rig_force_fault", None, [fw, ctypes.c_uint8]),
            ("rig_firmware_size", ctypes.c_uint32, []),
            ("rig_state", ctypes.c_uint8, [fw]), ("rig_fault", ctypes.c_uint8, [fw]),
            ("rig_flags", ctypes.c_uint8, [fw]), ("rig_counter", ctypes.c_uint32, [fw, ctypes.c_uint32]),
            ("rig_set_heartbeat_enabled", None, [fw, ctypes.c_bool])):
        function = getattr(lib, name)
        function.restype, function.argtypes = result, args
    return lib


#: rig_counter() indices, in FirmwareCounters' order, then the faults by code (rig_firmware.h)
_COUNTERS = ("accepted", "bad_crc", "bad_length", "bad_mode", "repeated_counter", "stale_counter", "ignored_in_boot",
             "watchdog_trips")
_FLAGS = {"watchdog": 1, "over_current": 2, "lvdt": 4, "travel": 8}


class CRigFirmware:
    """The C firmware core over Python hardware, with :class:`~firmware_proto.firmware.RigFirmware`'s interface.

    Parameters
    ----------
    hardware, limits, start_s, icd
        As :class:`~firmware_proto.firmware.RigFirmware`'s (``icd`` only for callers that read it: the C core
        has the ICD compiled in from the DBC).
    library : str, optional
        The library to load (default: :func:`library_path`).
    """

    def __init__(self, hardware: RigHardware, limits: FirmwareLimits, start_s: float = 0.0,
                 icd: Icd | None = None, library: str | None = None) -> None:
        self.hw = hardware
        self.limits = limits
        self.icd = icd or default_icd()
        self._lib = load_library(library)
        self._state = ctypes.create_string_buffer(self._lib.rig_firmware_size())
        self._out: list[Frame] = []
        self._heartbeat_enabled = True

        def send(_ctx: object, can_id: int, data: object, length: int) -> None:
            self._out.append((int(can_id), ctypes.string_at(data, length)))

        # kept on the object: ctypes callbacks must outlive every call into the library
        self._callbacks = _Hardware(_DOUBLE_FN(lambda _c: hardware.sample_position_mm()),
                                    _DOUBLE_FN(lambda _c: hardware.sample_current_a()),
                                    _DRIVE_FN(lambda _c, v: hardware.set_drive_v(v)),
                                    _DOUBLE_FN(lambda _c: hardware.supply_voltage_v()), _SEND_FN(send), None)
        c_limits = _Limits(*(getattr(limits, name) for name, _ in _Limits._fields_))
        self._lib.rig_init(self._state, ctypes.byref(self._callbacks), ctypes.byref(c_limits), start_s)

    def _frames(self) -> list[Frame]:
        out, self._out = self._out, []
        return out

    @property
    def state(self) -> RigState:
        """BOOT, READY, RUNNING or FAULT."""
        return RigState(self._lib.rig_state(self._state))

    @property
    def fault_code(self) -> FaultCode:
        """The first cause of a latched fault."""
        return FaultCode(self._lib.rig_fault(self._state))

    @property
    def flags(self) -> dict[str, bool]:
        """The latched fault flags."""
        bits = self._lib.rig_flags(self._state)
        return {name: bool(bits & bit) for name, bit in _FLAGS.items()}

    @property
    def counters(self) -> FirmwareCounters:
        """The diagnosis counters, as the Python firmware keeps them."""
        values = {name: int(self._lib.rig_counter(self._state, i)) for i, name in enumerate(_COUNTERS)}
        faults = {code.name: int(self._lib.rig_counter(self._state, len(_COUNTERS) + int(code)))
                  for code in FaultCode}
        return FirmwareCounters(**values, faults={name: n for name, n in faults.items() if n})

    @property
    def heartbeat_enabled(self) -> bool:
        """Fault injection: False stops the heartbeat."""
        return self._heartbeat_enabled

    @heartbeat_enabled.setter
    def heartbeat_enabled(self, enabled: bool) -> None:
        self._heartbeat_enabled = bool(enabled)
        self._lib.rig_set_heartbeat_enabled(self._state, bool(enabled))

    def next_deadline_s(self) -> float:
        """Earliest time at which :meth:`on_time` has something to do."""
        return float(self._lib.rig_next_deadline_s(self._state))

    def on_time(self, now_s: float) -> list[Frame]:
        """Run the timers due at ``now_s``; the frames sent."""
        self._lib.rig_on_time(self._state, now_s)
        return self._frames()

    def skip_missed_heartbeats(self, now_s: float) -> None:
        """The main loop was held up until ``now_s``: one heartbeat on resuming, not a burst."""
        self._lib.rig_skip_missed_heartbeats(self._state, now_s)

    def on_frame(self, can_id: int, data: bytes | bytearray, now_s: float) -> list[Frame]:
        """Handle one received frame; the frames sent (a reply first, then heartbeats)."""
        payload = bytes(data)[:255]  # the core checks the length first: anything but 8 bytes is not a command
        self._lib.rig_on_frame(self._state, can_id, payload, len(payload), now_s)
        return self._frames()

    def force_fault(self, code: FaultCode) -> list[Frame]:
        """Latch a fault from outside the protocol."""
        self._lib.rig_force_fault(self._state, int(code))
        return self._frames()


def c_firmware_available() -> bool:
    """Whether the library is built where :func:`library_path` looks."""
    return library_path().is_file()


__all__ = ["CFirmwareMissing", "CRigFirmware", "c_firmware_available", "library_path", "load_library"]
