"""Read a record folder back: record.json, its trace and its CAN log (the folder alone, nothing else)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from edc_bench.errors import ConfigError
from edc_bench.records.writer import CAN_LOG_FILE, RECORD_FILE, TRACE_FILE

#: A frame read back from a CAN log: time (s), CAN id, payload.
LoggedFrame = tuple[float, int, bytes]


def load_record(folder: Path) -> dict[str, Any]:
    """The parsed record.json of ``folder``.

    Raises
    ------
    ConfigError
        If the folder or its record.json is missing or unreadable, saying what to do.
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
    return record


def load_trace(folder: Path) -> dict[str, np.ndarray]:
    """The per-tick trace of a record folder."""
    path = Path(folder) / TRACE_FILE
    try:
        with np.load(path) as data:
            return {name: data[name] for name in data.files}
    except (OSError, ValueError) as exc:
        raise ConfigError(f"{path}: not a readable trace ({exc})") from None


def read_can_log(path: Path) -> list[LoggedFrame]:
    """Frames of a candump-style log written by edc-bench (or candump -L), in file order."""
    import can

    path = Path(path)
    if not path.exists():
        raise ConfigError(f"{path}: no such CAN log")
    try:
        return [(float(m.timestamp), int(m.arbitration_id), bytes(m.data))
                for m in can.CanutilsLogReader(str(path)) if not m.is_error_frame]
    except (OSError, ValueError) as exc:
        raise ConfigError(f"{path}: not a readable candump log ({exc})") from None
