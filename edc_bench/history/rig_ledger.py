"""The rig self-check's ledger as rows: each registration with its checks, each figure's drift and its trend
(``history --rig`` prints it; the web view's rigs page charts it)."""

from __future__ import annotations

import json
from typing import Any

#: The ledger's columns: a figure, its heading, and how its change is shown.
COLUMNS = (("lvdt_zero_mm", "LVDT zero", "mm"), ("current_zero_a", "current zero", "A"),
           ("coil_r20_ohm", "coil R", "%"), ("a0_v_per_mm", "a0", "%"), ("af_v", "af", "%"),
           ("a1_v_s_per_mm", "a1", "%"))


def ledger(store: Any, station: str | None) -> list[dict[str, Any]]:
    """Every registration (of one station if given), oldest first, each with its checks and each figure's trend."""
    out = []
    for reference in store.references(station):
        checks = []
        for row in store.rig_checks(reference["station"], reference["id"]):
            details = json.loads(row["details"] or "{}")
            figures = details.get("figures", {})
            checks.append({"id": row["id"], "checked_at": row["checked_at"], "verdict": row["verdict"],
                           "causes": [c for c in row["causes"].split(",") if c], "words": row["words"],
                           "checked_by": row["checked_by"], "simulated": row["simulated"],
                           "due": details.get("due") if row["verdict"] == "SKIPPED" else None,
                           "drift": {name: figures.get(name, {}).get("drift") for name, _, _ in COLUMNS},
                           "measured": {name: row[name] for name, _, _ in COLUMNS}})
        out.append({"reference": {key: reference[key] for key in (
            "id", "station", "valve_id", "variant", "registered_at", "registered_by", "simulated",
            *(name for name, _, _ in COLUMNS))}, "checks": checks, "trend_per_check": trend(checks)})
    return out


def trend(checks: list[dict[str, Any]]) -> dict[str, float | None]:
    """Each figure's change per check against the registration: the slope of a straight line through its changes
    (None with fewer than 3 checks that measured it)."""
    import numpy as np

    out: dict[str, float | None] = {}
    measured = [c for c in checks if c["verdict"] != "SKIPPED"]  # a skip measured nothing: no step of the trend
    for name, _, _ in COLUMNS:
        points = [(k, c["drift"][name]) for k, c in enumerate(measured) if c["drift"].get(name) is not None]
        out[name] = (float(np.polyfit([k for k, _ in points], [d for _, d in points], 1)[0]) if len(points) >= 3
                     else None)
    return out


