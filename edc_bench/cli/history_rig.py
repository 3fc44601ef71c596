"""``edc-bench history --rig``: the rig self-check's ledger: each registration, each check, and each figure's trend."""

from __future__ import annotations

import argparse
import json
import sys
from typing import Any

from edc_bench.cli.common import print_quietly_if_closed

#: The ledger's columns: a figure, its heading, and how its change is shown.
_COLUMNS = (("lvdt_zero_mm", "LVDT zero", "mm"), ("current_zero_a", "current zero", "A"),
            ("coil_r20_ohm", "coil R", "%"), ("a0_v_per_mm", "a0", "%"), ("af_v", "af", "%"),
            ("a1_v_s_per_mm", "a1", "%"))


_VERDICT_STYLES = {"GO": "green", "SKIPPED": "bold yellow"}


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
                           "drift": {name: figures.get(name, {}).get("drift") for name, _, _ in _COLUMNS},
                           "measured": {name: row[name] for name, _, _ in _COLUMNS}})
        out.append({"reference": {key: reference[key] for key in (
            "id", "station", "valve_id", "variant", "registered_at", "registered_by", "simulated",
            *(name for name, _, _ in _COLUMNS))}, "checks": checks, "trend_per_check": trend(checks)})
    return out


def trend(checks: list[dict[str, Any]]) -> dict[str, float | None]:
    """Each figure's change per check against the registration: the slope of a straight line through its changes
    (None with fewer than 3 checks that measured it)."""
    import numpy as np

    out: dict[str, float | None] = {}
    measured = [c for c in checks if c["verdict"] != "SKIPPED"]  # a skip measured nothing: no step of the trend
    for name, _, _ in _COLUMNS:
        points = [(k, c["drift"][name]) for k, c in enumerate(measured) if c["drift"].get(name) is not None]
        out[name] = (float(np.polyfit([k for k, _ in points], [d for _, d in points], 1)[0]) if len(points) >= 3
                     else None)
    return out


def _change(value: float | None, unit: str, sign: bool = True) -> str:
    if value is None:
        return ""
    if unit == "%":
        return f"{value * 100:{'+' if sign else ''}.2f} %"
    return f"{value:+.3f}" if unit == "mm" else f"{value:+.4f}"


def run_rig(args: argparse.Namespace) -> int:
    """Print the ledger (or its JSON)."""
    from edc_bench.errors import ConfigError
    from edc_bench.history.store import HistoryStore

    with HistoryStore(args.db, must_exist=True) as store:
        found = ledger(store, args.station)
        where = store.shown_url
    if not found:
        of = f" of station {args.station!r}" if args.station else ""
        raise ConfigError(f"no reference valve is registered{of} in {where}: register one with 'edc-bench "
                          "rig-selfcheck --register --valve-id ID'")
    if args.json:
        print_quietly_if_closed(lambda: print(json.dumps(found, indent=2)))
    else:
        print_quietly_if_closed(lambda: ledger_tables(found, where))
    return 0


def ledger_tables(found: list[dict[str, Any]], where: str, console: Any = None) -> None:
    """Print one table per registration: each check's change of each figure against the registration, and the trend."""
    from rich.console import Console
    from rich.table import Table
    from rich.text import Text

    from edc_bench.timefmt import local_column, local_text

    console = console or Console(width=None if sys.stdout.isatty() else 160)
    for entry in found:
        ref, checks = entry["reference"], entry["checks"]
        nogo = sum(c["verdict"] == "NO-GO" for c in checks)
        skipped = sum(c["verdict"] == "SKIPPED" for c in checks)
        checked, zone = local_column([c["checked_at"] for c in checks])
        title = Text(f"station {ref['station']}: reference valve {ref['valve_id']} ({ref['variant']}), registered "
                     f"{local_text(ref['registered_at'])} by {ref['registered_by']}"
                     + (" on the simulated rig" if ref["simulated"] else "")
                     + f"; {len(checks) - skipped} check(s), {nogo} NO-GO"
                     + (f", {skipped} due check(s) skipped by the technician" if skipped else "")
                     + f"; change against the registration ({zone}, "
                       f"{where})")
        table = Table(title=title)
        for col in ("check", "when", "by", "verdict", *(f"{label} {unit}" for _, label, unit in _COLUMNS),
                    "drifted"):
            table.add_column(col, no_wrap=col not in ("drifted", "by"))
        for c, when in zip(checks, checked, strict=True):  # "by": the operator who ran it, as typed: never markup
            table.add_row(str(c["id"]), when, Text(c.get("checked_by") or ""),
                          Text(c["verdict"], style=_VERDICT_STYLES.get(c["verdict"], "bold red")),
                          *(_change(c["drift"][name], unit) for name, _, unit in _COLUMNS),
                          Text(", ".join(c["causes"]) if c["verdict"] != "SKIPPED" else f"skipped; it was due: {c['due'] or 'not recorded'}"))
        per_check = entry["trend_per_check"]
        if any(v is not None for v in per_check.values()):
            table.add_row("trend", "per check", "", "",
                          *(_change(per_check[name], unit) for name, _, unit in _COLUMNS), "")
        console.print(table)
