"""Read a record folder back: record.json, its trace and its CAN log (the folder alone, nothing else)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from edc_bench.errors import ConfigError
from edc_bench.protocol.icd import BENCH_CMD_ID
from edc_bench.records.schema import Record
from edc_bench.records.integrity import altered
from edc_bench.records.writer import CAN_LOG_FILE, LEGACY_TRACE_FILE, RECORD_FILE, TRACE_FILE

#: A frame read back from a CAN log: time (s), CAN id, payload.
LoggedFrame = tuple[float, int, bytes]


def load_record(folder: Path, *, check_integrity: bool = True) -> Record:
    """The record.json of ``folder``, typed (an older schema read in today's form).

    With ``check_integrity`` (the default), a record changed since its test wrote it is refused
    (:mod:`~edc_bench.records.integrity`); replay reads it all the same and reports the change as a difference.

    Raises
    ------
    ConfigError
        If the folder or its record.json is missing or unreadable, changed after the test (naming what changed),
        or a field holds what it cannot (naming the field and what it holds), saying what to do.
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise ConfigError(f"{folder}: no such record folder (give a folder written by 'edc-bench test')")
    path = folder / RECORD_FILE
    if not path.exists():
        raise ConfigError(f"{folder}: no {RECORD_FILE}; the test did not finish writing its record "
                          f"(its {CAN_LOG_FILE} may still be replayed with --can-log and --variant)")
    try:
        record = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise ConfigError(f"{path}: not a readable record ({exc})") from None
    if not isinstance(record, dict) or "verdict" not in record:
        raise ConfigError(f"{path}: not an edc-bench record (no verdict)")
    if check_integrity:
        changes = altered(record, folder)
        if changes:
            raise ConfigError(f"{folder}: changed after its test wrote it ({', '.join(changes)}): not read. 'edc-bench "
                              "replay' of the folder shows what the test's own CAN log gives")
    return typed_record(upgraded(record), path)


def changed_since_written(folder: Path) -> list[str]:
    """What in the record folder changed since its test wrote it (:func:`~edc_bench.records.integrity.altered`;
    empty for a record too old to say)."""
    try:
        record = json.loads((Path(folder) / RECORD_FILE).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return []  # load_record says why it cannot be read
    return altered(record, Path(folder)) if isinstance(record, dict) else []


def typed_record(record: dict[str, Any], source: Path | str) -> Record:
    """``record`` (record.json's content, today's schema) as a :class:`Record`, or a ConfigError naming the field."""
    from pydantic import ValidationError

    try:
        return Record.model_validate(record)
    except ValidationError as exc:
        error = exc.errors()[0]
        where = ".".join(str(part) for part in error["loc"]) or "record"
        shown = repr(error.get("input"))
        shown = shown if len(shown) <= 60 else shown[:57] + "..."
        more = f" (and {exc.error_count() - 1} more)" if exc.error_count() > 1 else ""
        raise ConfigError(f"{source}: not a readable edc-bench record: {where} holds {shown}: {error['msg']}{more}; "
                          "a record is written whole by 'edc-bench test': correct the hand-edited field, or "
                          "replay the test from its can.log") from None


def upgraded(record: dict[str, Any]) -> dict[str, Any]:
    """A record of an older schema in today's form, so that every reader reads one form: each schema's step in
    turn (:func:`_to_schema_4`, :func:`_to_schema_10`). This module is the one place that knows an older record's
    wording."""
    version = int(record.get("schema") or 0)
    if version < 4:
        record = _to_schema_4(record)
    if version < 10:
        record = _to_schema_10(record)
    return record


def _to_schema_10(record: dict[str, Any]) -> dict[str, Any]:
    """Schema 10 keeps where the baseline's tests ran as values (``baseline.sources``); an older record names them
    only in its ``baseline.source`` sentence, read here once."""
    baseline = record.get("baseline")
    if not isinstance(baseline, dict) or "sources" in baseline:
        return record
    from edc_bench.verdict.baseline_source import BaselineSource, sources_of_text

    tests = baseline.get("tests")
    sources = ({BaselineSource.NOMINAL} if not tests
               else sources_of_text(baseline.get("source") if isinstance(baseline.get("source"), str) else ""))
    return {**record, "baseline": {**baseline, "sources": sorted(str(source) for source in sources)}}


def _to_schema_4(record: dict[str, Any]) -> dict[str, Any]:
    """Schema 4 gave as values what older records held only as sentences: the verdict's ``problems``, whether
    the coil's temperature was given (``coil.temp_given``), the abort's kind (``loop.abort``; an older one
    becomes kind ``recorded``, its sentence kept), and the timing's ``ticks_late`` (formerly ``overruns``).
    Reading those sentences is this function's alone: it is the one place that knows the old wording. An older
    record's ``problems`` hold ``aborted`` and ``not calibrated``, what its values and that wording show; the trust
    rule's other problems stay in its reasons only.
    """
    from edc_bench.engine.outcome import abort_from_record

    record = dict(record)
    reasons = [str(r) for r in record.get("reasons") or []]
    aborted = bool((record.get("loop") or {}).get("abort_reason"))
    not_calibrated = any(r.startswith("variant not calibrated") for r in reasons)
    record.setdefault("problems", ["aborted"] * aborted + ["not calibrated"] * not_calibrated)
    if isinstance(record.get("coil"), dict):
        coil = dict(record["coil"])
        coil.setdefault("temp_given", str(coil.get("temp_source", "")).startswith("given"))
        record["coil"] = coil
    if isinstance(record.get("timing"), dict) and "ticks_late" not in record["timing"]:
        record["timing"] = {**record["timing"], "ticks_late": record["timing"].get("overruns", 0)}
    if isinstance(record.get("loop"), dict) and "abort" not in record["loop"]:
        abort = abort_from_record(record["loop"])
        record["loop"] = {**record["loop"], "abort": None if abort is None else abort.as_dict()}
    return record


def load_trace(folder: Path) -> dict[str, np.ndarray]:
    """The per-tick trace of a record folder (``trace.mf4``; ``trace.npz`` in records before schema 3)."""
    path = Path(folder) / TRACE_FILE
    if path.exists():
        from edc_bench.records.mdf import read_trace_mf4

        return read_trace_mf4(path)
    path = Path(folder) / LEGACY_TRACE_FILE
    if not path.exists():
        raise ConfigError(f"{folder}: the record folder has no trace ({TRACE_FILE})")
    try:
        with np.load(path) as data:
            return {name: data[name] for name in data.files}
    except (OSError, ValueError) as exc:
        raise ConfigError(f"{path}: not a readable trace ({exc})") from None


#: CAN log formats replay reads, by file suffix (python-can's readers; each may also be gzipped, ``.asc.gz``).
CAN_LOG_FORMATS = {".log": "candump -L (the record's can.log)", ".asc": "Vector ASC", ".blf": "Vector BLF",
                   ".mf4": "ASAM MDF 4 bus logging (also a record's trace.mf4)", ".trc": "PEAK TRC",
                   ".csv": "python-can CSV", ".db": "python-can SQLite"}


def _log_suffix(path: Path) -> str:
    suffixes = [s.lower() for s in path.suffixes]
    return suffixes[-2] if len(suffixes) >= 2 and suffixes[-1] == ".gz" else (suffixes[-1] if suffixes else "")


def _unreadable(path: Path, kind: str, read: int, exc: Exception) -> str:
    """Why a CAN log could not be read, for people: a candump log cut short names its last line and "truncated"."""
    if path.suffix.lower() == ".log":
        lines = path.read_bytes().splitlines(keepends=True)
        data_lines = [i for i, line in enumerate(lines, 1) if line.strip() and not line.lstrip().startswith(b"#")]
        if read < len(data_lines):
            number = data_lines[read]
            if number == len(lines) and not lines[-1].endswith(b"\n"):
                return (f"{path}: line {number} is cut short: the log is truncated (a copy that stopped early, or a "
                        f"full disk); the {read} frames before it read fine")
            return f"{path}: line {number} is not a {kind} line ({lines[number - 1][:60]!r})"
    return f"{path}: not a readable {kind} CAN log ({type(exc).__name__}: {exc})"


def read_can_log(path: Path) -> list[LoggedFrame]:
    """Frames of a CAN log in any format python-can reads, in file order; error frames left out.

    The format follows the suffix (:data:`CAN_LOG_FORMATS`): the record's own
    candump ``can.log``, or the same log converted by ``python -m can.logconvert``
    or written by another tool (ASC, BLF, MF4 bus logging, TRC).

    Raises
    ------
    ConfigError
        If the file is missing, its suffix is not a CAN log format, or it cannot be read as one.
    """
    from edc_bench.canlib import can, mf4_module

    path = Path(path)
    if not path.is_file():
        raise ConfigError(f"{path}: no such CAN log file")
    suffix = _log_suffix(path)
    if suffix not in CAN_LOG_FORMATS:
        known = ", ".join(f"{s} ({name})" for s, name in CAN_LOG_FORMATS.items())
        raise ConfigError(f"{path}: {suffix or 'no suffix'} is not a CAN log format edc-bench reads; "
                          f"the suffix names the format: {known}")
    if suffix == ".mf4":
        mf4_module()  # python-can's MF4 reader, with asammdf
    if suffix == ".mf4" and path.suffix.lower() == ".mf4":
        from edc_bench.records.mdf import looks_like_mdf4

        if not looks_like_mdf4(path):
            raise ConfigError(f"{path}: not a readable {CAN_LOG_FORMATS[suffix]} CAN log (not an MDF 4 file)")
    read = 0  # messages the reader gave before any error
    try:
        messages = []
        with can.LogReader(str(path)) as reader:
            for m in reader:
                read += 1
                # the ICD's frames are standard data frames: extended, remote and error frames are other traffic
                if not (m.is_error_frame or m.is_remote_frame or m.is_extended_id):
                    messages.append(m)
        if any(not m.is_rx for m in messages):  # a log that records directions: a BENCH_CMD read is another host's
            messages = [m for m in messages if not (m.is_rx and m.arbitration_id == BENCH_CMD_ID)]
        frames = [(float(m.timestamp), int(m.arbitration_id), bytes(m.data)) for m in messages]
    except Exception as exc:  # noqa: BLE001 - each format's reader raises its own error types on a bad file
        raise ConfigError(_unreadable(path, CAN_LOG_FORMATS[suffix], read, exc)) from None
    if not frames and path.stat().st_size > 0:
        raise ConfigError(f"{path}: holds no CAN data frames ({CAN_LOG_FORMATS[suffix]}); a damaged file, or a "
                          "log of no bench test")
    return frames
