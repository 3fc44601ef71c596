"""``edc-bench history --rig``: the rig self-check's ledger: each registration, each check, and each figure's trend."""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from typing import Any

from edc_bench.cli.common import print_quietly_if_closed
from edc_bench.history.rig_ledger import COLUMNS as _COLUMNS
from edc_bench.history.rig_ledger import LedgerEntry, ledger

_VERDICT_STYLES = {"GO": "green", "SKIPPED": "bold yellow"}


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
        print_quietly_if_closed(lambda: print(json.dumps([dataclasses.asdict(e) for e in found], indent=2)))
    else:
        print_quietly_if_closed(lambda: ledger_tables(found, where))
    return 0


def ledger_tables(found: list[LedgerEntry], where: str, console: Any = None) -> None:
    """Print one table per registration: each check's change of each figure against the registration, and the trend."""
    from rich.console import Console
    from rich.table import Table
    from rich.text import Text

    from edc_bench.timefmt import local_column, local_text

    console = console or Console(width=None if sys.stdout.isatty() else 160)
    for entry in found:
        ref, checks = entry.reference, entry.checks
        nogo = sum(c.verdict == "NO-GO" for c in checks)
        skipped = sum(c.verdict == "SKIPPED" for c in checks)
        checked, zone = local_column([c.checked_at for c in checks])
        title = Text(f"station {ref.station}: reference valve {ref.valve_id} ({ref.variant}), registered "
                     f"{local_text(ref.registered_at)} by {ref.registered_by}"
                     + (" on the simulated rig" if ref.simulated else "")
                     + f"; {len(checks) - skipped} check(s), {nogo} NO-GO"
                     + (f", {skipped} due check(s) skipped by the technician" if skipped else "")
                     + f"; change against the registration ({zone}, "
                       f"{where})")
        table = Table(title=title)
        for col in ("check", "when", "by", "verdict", *(f"{label} {unit}" for _, label, unit in _COLUMNS),
                    "drifted"):
            table.add_column(col, no_wrap=col not in ("drifted", "by"))
        for c, when in zip(checks, checked, strict=True):  # "by": the operator who ran it, as typed: never markup
            table.add_row(str(c.id), when, Text(c.checked_by or ""),
                          Text(c.verdict, style=_VERDICT_STYLES.get(c.verdict, "bold red")),
                          *(_change(c.drift[name], unit) for name, _, unit in _COLUMNS),
                          Text(", ".join(c.causes) if c.verdict != "SKIPPED"
                               else f"skipped; it was due: {c.due or 'not recorded'}"))
        per_check = entry.trend_per_check
        if any(v is not None for v in per_check.values()):
            table.add_row("trend", "per check", "", "",
                          *(_change(per_check[name], unit) for name, _, unit in _COLUMNS), "")
        console.print(table)
