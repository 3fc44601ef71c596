"""Write a test's record folder: record.json, trace.npz, can.log, report.png.

Every file is written atomically (temporary file, flush, fsync, rename), so a
record file is either complete or absent, never half-written.
"""

from __future__ import annotations

import json
import math
import re
from pathlib import Path
from typing import Any

import numpy as np

from edc_bench.paths import atomic_write

RECORD_SCHEMA = 1
TRACE_FILE = "trace.npz"
CAN_LOG_FILE = "can.log"
FIGURE_FILE = "report.png"
RECORD_FILE = "record.json"


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
