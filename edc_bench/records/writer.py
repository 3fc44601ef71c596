"""Write a test's record folder: record.json, trace.npz, can.log, report.png.

Every file is written atomically (temporary file, flush, fsync, rename), so a
record file is either complete or absent, never half-written.
"""

from __future__ import annotations

import json
import math
import os
import re
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

RECORD_SCHEMA = 1
TRACE_FILE = "trace.npz"
CAN_LOG_FILE = "can.log"
FIGURE_FILE = "report.png"
RECORD_FILE = "record.json"


def atomic_write(path: Path, write: Callable[[Any], None], mode: str = "wb") -> None:
    """Write ``path`` through ``write(fileobj)`` atomically.

    Parameters
    ----------
    path : pathlib.Path
        Final file path.
    write : callable
        Receives the open temporary file and writes the content.
    mode : str
        ``"wb"`` or ``"w"``.
    """
    path = Path(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
    try:
        with os.fdopen(fd, mode, **({} if "b" in mode else {"encoding": "utf-8"})) as handle:
            write(handle)
            handle.flush()
            os.fsync(handle.fileno())
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    dir_fd = os.open(path.parent, os.O_RDONLY)
    try:
        os.fsync(dir_fd)  # the rename itself survives a power cut
    finally:
        os.close(dir_fd)


def json_safe(value: Any) -> Any:
    """Replace NaN and infinities (not valid JSON) with None, recursively."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {str(k): json_safe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [json_safe(v) for v in value]
    if isinstance(value, np.generic):
        return json_safe(value.item())
    return value


def new_record_dir(out_dir: Path, valve_id: str, variant: str, started_at: str) -> Path:
    """Create a fresh folder for one test's record."""
    stamp = re.sub(r"[^0-9T]", "", started_at.split("+")[0])
    safe_id = re.sub(r"[^A-Za-z0-9_.-]+", "_", valve_id or "valve").strip("_") or "valve"
    out_dir.mkdir(parents=True, exist_ok=True)
    base = out_dir / f"{stamp}-{variant}-{safe_id}"
    path, n = base, 1
    while True:
        try:
            path.mkdir()
            return path
        except FileExistsError:
            n += 1
            path = Path(f"{base}-{n}")


def write_trace(path: Path, trace: dict[str, np.ndarray]) -> None:
    """Per-tick trace as a compressed .npz (one array per column)."""
    atomic_write(path, lambda f: np.savez_compressed(f, **trace))


def write_can_log(path: Path, frames: Any, channel: str = "can0") -> None:
    """Raw CAN traffic as a candump-style .log that python-can reads back (``can.LogReader``)."""
    import can

    def write(handle: Any) -> None:
        writer = can.CanutilsLogWriter(handle, channel=channel)
        for k in range(frames.count):
            dlc = int(frames.dlc[k])
            writer.on_message_received(can.Message(
                timestamp=float(frames.t_s[k]), arbitration_id=int(frames.can_id[k]), is_extended_id=False,
                dlc=dlc, data=bytes(frames.data[k, :dlc]), is_rx=bool(frames.rx[k]), channel=channel,
            ))

    atomic_write(path, write, mode="w")


def write_json(path: Path, data: dict[str, Any]) -> None:
    """JSON file, atomically."""
    atomic_write(path, lambda f: json.dump(json_safe(data), f, indent=2, sort_keys=False), mode="w")
