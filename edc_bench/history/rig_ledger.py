"""The rig self-check's ledger as rows: each registration with its checks, each figure's drift and its trend
(``history --rig`` prints it; the web view's rigs page charts it)."""

from __future__ import annotations

import json
from dataclasses import dataclass
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from edc_bench.history.rows import ReferenceRow
    from edc_bench.history.store import HistoryStore

#: The ledger's columns: a figure, its heading, and how its change is shown.
COLUMNS = (("lvdt_zero_mm", "LVDT zero", "mm"), ("current_zero_a", "current zero", "A"),
           ("coil_r20_ohm", "coil R", "%"), ("a0_v_per_mm", "a0", "%"), ("af_v", "af", "%"),
           ("a1_v_s_per_mm", "a1", "%"))


@dataclass(frozen=True)
class LedgerCheck:
    """One self-check (or skipped due check) in the ledger."""

    id: int
    checked_at: str
    #: GO, NO-GO or SKIPPED
    verdict: str
    #: the drifts named
    causes: list[str]
    words: str
    checked_by: str
    simulated: bool
    #: for a skipped check: why it was due
    due: str | None
    #: each figure's change against the registration (None: not compared)
    drift: dict[str, float | None]
    #: each figure as measured
    measured: dict[str, float | None]


@dataclass(frozen=True)
class LedgerReference:
    """A registration as the ledger shows it, with its figures as registered (None: not measured)."""

    id: int
    station: str
    valve_id: str
    variant: str
    registered_at: str
    registered_by: str
    simulated: bool
    lvdt_zero_mm: float | None
    current_zero_a: float | None
    coil_r20_ohm: float | None
    a0_v_per_mm: float | None
    af_v: float | None
    a1_v_s_per_mm: float | None


@dataclass(frozen=True)
class LedgerEntry:
    """A registration, its checks, and each figure's trend (change per check: :func:`trend`)."""

    reference: LedgerReference
    checks: list[LedgerCheck]
    trend_per_check: dict[str, float | None]


def ledger(store: HistoryStore, station: str | None) -> list[LedgerEntry]:
    """Every registration (of one station if given), oldest first, each with its checks and each figure's trend."""
    out = []
    for reference in store.references(station):
        checks = []
        for row in store.rig_checks(reference.station, reference.id):
            details = json.loads(row.details or "{}")
            figures = details.get("figures", {})
            checks.append(LedgerCheck(
                id=row.id, checked_at=row.checked_at, verdict=row.verdict,
                causes=[c for c in row.causes.split(",") if c], words=row.words, checked_by=row.checked_by,
                simulated=row.simulated, due=details.get("due") if row.verdict == "SKIPPED" else None,
                drift={name: figures.get(name, {}).get("drift") for name, _, _ in COLUMNS},
                measured=row.figures()))
        out.append(LedgerEntry(_reference(reference), checks, trend(checks)))
    return out


def _reference(row: ReferenceRow) -> LedgerReference:
    return LedgerReference(id=row.id, station=row.station, valve_id=row.valve_id, variant=row.variant,
                           registered_at=row.registered_at, registered_by=row.registered_by,
                           simulated=row.simulated, **row.figures())


def trend(checks: list[LedgerCheck]) -> dict[str, float | None]:
    """Each figure's change per check against the registration: the slope of a straight line through its changes
    (None with fewer than 3 checks that measured it)."""
    import numpy as np

    out: dict[str, float | None] = {}
    measured = [c for c in checks if c.verdict != "SKIPPED"]  # a skip measured nothing: no step of the trend
    for name, _, _ in COLUMNS:
        points = [(k, c.drift[name]) for k, c in enumerate(measured) if c.drift.get(name) is not None]
        out[name] = (float(np.polyfit([k for k, _ in points], [d for _, d in points], 1)[0]) if len(points) >= 3
                     else None)
    return out
