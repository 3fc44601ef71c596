"""The C firmware core (``c/``), loaded with ctypes behind the same interface as :class:`~firmware_proto.firmware.RigFirmware`.

The simulated rig runs either firmware over the same plant (``edc-bench rig --firmware c``), and the firmware
tests run against both. The host library is built on first use, with ``c/Makefile`` (make, a C compiler and
cantools), into the user's cache folder, one folder per digest of what it is built from
(:func:`cached_library_path`): never inside the installed package, rebuilt when the sources change, and shared by
every later run. Without make or a compiler :func:`load_library` says in one line what is missing.
``EDC_BENCH_C_FIRMWARE`` names a library built elsewhere.
"""

from __future__ import annotations

import ctypes
import hashlib
import importlib.metadata
import os
import platform
import shutil
import subprocess
import sys
import tempfile
from functools import lru_cache
from pathlib import Path

from edc_bench.protocol import FaultCode, Icd, RigState, dbc_path, default_icd
from firmware_proto.firmware import FirmwareCounters, FirmwareLimits, Frame, RigHardware

LIBRARY_ENV = "EDC_BENCH_C_FIRMWARE"
C_DIR = Path(__file__).resolve().parent / "c"
LIBRARY_NAME = "libedcrig.so"

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
    """The C firmware library is not there and cannot be built here (the message says what is missing)."""


def _cache_root() -> Path:
    """edc-bench's cache folder, found as ``edc_bench.paths.cache_dir`` finds it: ``EDC_BENCH_CACHE_DIR``, else the
    user's cache folder (``XDG_CACHE_HOME`` on Linux, by platformdirs). Read here, not imported: the firmware
    imports nothing of the bench's but the protocol (pyproject.toml's import contracts)."""
    configured = os.environ.get("EDC_BENCH_CACHE_DIR")
    if configured:
        return Path(configured)
    from platformdirs import user_cache_dir

    return Path(user_cache_dir("edc-bench", appauthor=False))


def sources_digest() -> str:
    """SHA-256 of what the host library is built from: ``c/src`` and the Makefile, the ICD's DBC its frame codec is
    generated from, cantools' version (the generator) and the machine it is built for."""
    digest = hashlib.sha256()
    for path in [*sorted((C_DIR / "src").glob("*.[ch]")), C_DIR / "Makefile", dbc_path()]:
        digest.update(f"{path.name}\0{len(path.read_bytes())}\0".encode())
        digest.update(path.read_bytes())
    digest.update(f"cantools {importlib.metadata.version('cantools')} {sys.platform} {platform.machine()}".encode())
    return digest.hexdigest()


def cached_library_path() -> Path:
    """Where the first use builds the library: ``<cache>/firmware-<digest of the sources>/libedcrig.so``."""
    return _cache_root() / f"firmware-{sources_digest()[:16]}" / LIBRARY_NAME


def library_path() -> Path:
    """Where the library is looked for: ``EDC_BENCH_C_FIRMWARE``, else :func:`cached_library_path`."""
    return Path(os.environ.get(LIBRARY_ENV) or cached_library_path())


def build_library(folder: Path | None = None) -> Path:
    """Build the host library with ``c/Makefile`` into ``folder`` (default: :func:`cached_library_path`'s).

    make writes only below ``BUILD``: the package's own folder is read, never written. The build goes to a
    temporary folder beside ``folder`` and is renamed into place whole, so a run that starts meanwhile never loads
    half a library, and of two first uses at once the second keeps the first's.

    Parameters
    ----------
    folder : pathlib.Path, optional
        The folder to hold ``libedcrig.so`` (made; must not exist yet, or already hold a build).

    Returns
    -------
    pathlib.Path
        The library.

    Raises
    ------
    CFirmwareMissing
        In one line: make or a C compiler missing, the folder not writable, or the build failed (its output kept
        in a log file beside the folder).
    """
    folder = Path(folder) if folder is not None else cached_library_path().parent
    compiler = (os.environ.get("CC") or "cc").split()[0]
    missing = [what for what, program in (("make", "make"), (f"C compiler ({compiler})", compiler))
               if not shutil.which(program)]
    if missing:
        raise CFirmwareMissing(f"the C firmware is built on first use, and this machine has no "
                               f"{' and no '.join(missing)}: install {'them' if len(missing) > 1 else 'it'} "
                               f"(Debian: apt-get install make gcc), or set {LIBRARY_ENV} to a {LIBRARY_NAME} "
                               "built elsewhere")
    try:
        folder.parent.mkdir(parents=True, exist_ok=True)
        work = Path(tempfile.mkdtemp(prefix=f".{folder.name}-", dir=folder.parent))
    except OSError as exc:
        raise CFirmwareMissing(f"cannot build the C firmware in {folder.parent} ({exc.strerror}): set "
                               f"EDC_BENCH_CACHE_DIR to a folder this user can write, or {LIBRARY_ENV} to a "
                               f"{LIBRARY_NAME} built elsewhere") from None
    print(f"building the C firmware into {folder} (once for these sources)", file=sys.stderr, flush=True)
    done = subprocess.run(["make", "-C", str(C_DIR), f"BUILD={work}", f"PYTHON={sys.executable}", f"DBC={dbc_path()}"],
                          stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    if done.returncode != 0:
        shutil.rmtree(work, ignore_errors=True)
        log = folder.with_name(f"{folder.name}-build.log")
        log.write_text(done.stdout, encoding="utf-8")
        last = next((line.strip() for line in reversed(done.stdout.splitlines()) if line.strip()), "no output")
        raise CFirmwareMissing(f"building the C firmware failed ({last}); make's output is in {log}")
    try:
        os.rename(work, folder)
    except OSError:  # built meanwhile by another run (or left by an earlier one): keep that one
        shutil.rmtree(work, ignore_errors=True)
        if not (folder / LIBRARY_NAME).is_file():
            raise CFirmwareMissing(f"{folder} exists without {LIBRARY_NAME}: remove it, and the next run builds "
                                   "the C firmware again") from None
    return folder / LIBRARY_NAME


def load_library(path: str | None = None) -> ctypes.CDLL:
    """The C firmware library, its functions typed: ``path``, else ``EDC_BENCH_C_FIRMWARE``, else the user's cache
    build of these sources, built here on first use (:func:`build_library`).

    Raises
    ------
    CFirmwareMissing
        If the library named is missing or does not load, or cannot be built: in one line, what to do.
    """
    given = path or os.environ.get(LIBRARY_ENV)
    if given:
        where = Path(given)
        if not where.is_file():
            how = f"unset {LIBRARY_ENV} to build it on first use, or " if not path else ""
            raise CFirmwareMissing(f"the C firmware library {where} is missing: {how}build one with "
                                   f"'make -C {C_DIR} BUILD=DIR' (needs make and gcc)")
    else:
        where = cached_library_path()
        if not where.is_file():
            where = build_library(where.parent)
    try:
        return _typed(str(where))
    except OSError as exc:
        raise CFirmwareMissing(f"the C firmware library {where} does not load ({exc}): remove it and build it "
                               "again") from None


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
    """Whether the library is built where :func:`library_path` looks (nothing is built to find out)."""
    return library_path().is_file()


__all__ = ["CFirmwareMissing", "CRigFirmware", "build_library", "c_firmware_available", "cached_library_path",
           "library_path", "load_library", "sources_digest"]
