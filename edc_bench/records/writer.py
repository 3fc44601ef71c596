"""Write a test's record folder: record.json, trace.mf4, can.log, report.png.

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
from pydantic import BaseModel

from edc_bench.paths import atomic_write
from edc_bench.timefmt import folder_stamp

# 2: reference values, the judging model's file and SHA-256, the decision plane; absolute CAN-log times
# 3: the trace as ASAM MDF 4 (trace.mf4, with the CAN frames); the judging model's name
# 4: the controller's sums in today's order (replay to the bit); 5: record.json carries its integrity manifest
# (records.integrity); 6: af and a1 are the period fit over the core rows (#37)
# 7: the interval carries the held gain terms' error and the repeating residual (#37)
RECORD_SCHEMA = 13  # 8: the test's own id (test_id), made at its start: the history's key for the test (#51); 9: host
#                    stalls cost the rows they touched, not the test (the trust rule's timing, #53); 10: the baseline's
#                    sources as values (baseline.sources), not only its sentence (#54); 11: the part at fault
#                    (part: the valve, the rack or the rack-travel sensor, #67; older records: "valve only judged");
#                    12: the part's sensor gain with the solenoid's pull along the stroke, an uneven sensor told
#                    from a bind (#67: replay notes that a schema 11 record's part may differ); 13: the part
#                    allows the pump's return spring within the type's tolerance, and the baseline says how many
#                    pumps it ran in (baseline.pumps; #67: replay notes that an older record's part may differ)
TRACE_FILE = "trace.mf4"  # ASAM MDF 4 (records.mdf); records before schema 3 hold trace.npz
LEGACY_TRACE_FILE = "trace.npz"
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
    if isinstance(value, BaseModel):  # a record's section: its serialisation
        return json_safe(value.model_dump(mode="json", by_alias=True))
    return value


def new_record_dir(out_dir: Path, valve_id: str, variant: str, started_at: str) -> Path:
    """Create a fresh folder for one test's record, named by its local start time with the offset (a person browses
    the folders; record.json keeps UTC), the variant and the valve."""
    stamp = folder_stamp(started_at)
    # letters and digits of any script kept ("Ölventil" stays Ölventil); what a file system or a shell would take
    # otherwise (separators, spaces, quotes, control characters) becomes '_'
    safe_id = re.sub(r"[^\w.-]+", "_", valve_id or "valve").strip("_.") or "valve"
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


def write_can_log(path: Path, frames: Any) -> None:
    """Raw CAN traffic as a candump-style .log that python-can reads back (``can.LogReader``), atomically."""
    from edc_bench.records.stream import log_frames, open_log_writer

    atomic_write(path, lambda handle: log_frames(open_log_writer(handle), frames, 0, frames.count), mode="w")


def write_json(path: Path, data: dict[str, Any]) -> None:
    """JSON file, atomically."""
    atomic_write(path, lambda f: json.dump(json_safe(data), f, indent=2, sort_keys=False), mode="w")
