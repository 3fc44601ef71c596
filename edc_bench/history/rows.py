"""The history's rows as its readers get them: one typed value per table (:mod:`edc_bench.history.schema`).

A row is read by attribute (``row.verdict``), not by a column's name as text; each class lists its table's columns
in the table's order (``tests/history/test_rows.py`` holds the two together), with the values a query adds beside
them. Rows written before a column existed read it as None. The chain's own checks (``--verify``) read the stored
columns as the database gives them, as mappings: what is hashed is the row as stored, not a model of it.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, Self


class _Columns:
    """Built from a database row's mapping: its known columns taken, any other label a query added left out."""

    __slots__ = ()  # the rows' own slots only: a listing of many rows keeps no dict per row

    @classmethod
    def of(cls, mapping: Mapping[str, Any]) -> Self:
        """The row of a query's mapping (``row._mapping``): the columns and extras this class knows."""
        names = _field_names(cls)
        if names.issuperset(mapping.keys()):  # a query of this row's columns only: taken as they are (most reads)
            return cls(**mapping)
        return cls(**{key: value for key, value in mapping.items() if key in names})

    def columns(self) -> dict[str, object]:
        """The row's values by column name, in order (for JSON and CSV)."""
        return {name: getattr(self, name) for name in _field_order(type(self))}


_FIELD_NAMES: dict[type, frozenset[str]] = {}
_FIELD_ORDER: dict[type, tuple[str, ...]] = {}


def _field_order(cls: type) -> tuple[str, ...]:
    """A row type's fields in order (looked up once per type: a listing reads many rows)."""
    order = _FIELD_ORDER.get(cls)
    if order is None:
        order = _FIELD_ORDER[cls] = tuple(f.name for f in dataclasses.fields(cls))
    return order


def _field_names(cls: type) -> frozenset[str]:
    names = _FIELD_NAMES.get(cls)
    if names is None:
        names = _FIELD_NAMES[cls] = frozenset(_field_order(cls))
    return names

#: Teardown findings and the class each teaches the classifier (1: the valve must be replaced).
FINDINGS: dict[str, int] = {"reusable": 0, "worn": 1, "faulty": 1}


@dataclass(frozen=True, kw_only=True, slots=True)
class TestRow(_Columns):
    """One indexing of a test (table ``tests``): what its record said, and how it was indexed.

    ``changes``, ``chain_hash`` and ``first_id`` are not columns: a listing adds how often the test was indexed
    again with other content and its row's chain hash; a change names the row that stands. A listing's rows
    (:meth:`~edc_bench.history.store.HistoryStore.list`) hold the listed columns only (:data:`LIST_COLUMNS`): how
    the row was indexed and chained reads None there (``indexed``, ``first_indexing`` and ``audit`` read them).
    """

    __test__ = False  # a test's row, not a test: pytest does not collect it where a test imports it

    id: int
    record_dir: str
    started_at: str
    valve_id: str
    pump_serial: str
    variant: str
    part_number: str
    verdict: str
    af_v: float | None = None
    a1_v_s_per_mm: float | None = None
    af_rel: float | None = None
    a1_rel: float | None = None
    probability_faulty: float | None = None
    distance: float | None = None
    station: str
    operator: str
    clock: str
    software_version: str
    reason: str
    model_name: str | None = None
    model_sha256: str | None = None
    coil_r20_ohm: float | None = None
    coil_in_spec: bool | None = None
    model_fits: bool | None = None
    stop_reason: str | None = None
    test_s: float | None = None
    simulated: bool | None = None
    retest_of: str | None = None
    decision: str | None = None
    record_sha256: str | None = None
    record_manifest: str | None = None
    indexed_at: str | None = None
    indexed_by: str | None = None
    db_login: str | None = None
    test_key: str | None = None
    legacy_key: str | None = None
    prev_hash: str | None = None
    row_hash: str | None = None
    invalid_area: str | None = None
    first_indexing: bool | None = None
    part: str | None = None  # the part at fault; None: indexed before revision 0010 (the valve alone judged)
    # -- not columns: what a query adds
    #: how many times the test was indexed again with other content after this row (a listing's)
    changes: int | None = None
    #: the row's chain hash as a listing shows it (what a customer's report prints)
    chain_hash: str | None = None
    #: for a change: the row that stands (its test's first indexing)
    first_id: int | None = None

    def listed(self) -> dict[str, object]:
        """The row as a listing gives it (``history --json``, ``--csv``): :data:`LIST_COLUMNS`' values."""
        return {name: getattr(self, name) for name in LIST_COLUMNS}


#: The values :class:`TestRow` adds to the ``tests`` table's columns.
TEST_ROW_EXTRAS = ("changes", "chain_hash", "first_id")

#: The columns of ``tests`` a listing leaves out: how a row was indexed and chained, not what the test was (``--audit``
#: and ``--verify`` read them).
NOT_LISTED = ("record_manifest", "db_login", "prev_hash", "row_hash", "legacy_key", "first_indexing")

#: A listing's columns (``history --json`` and ``--csv``), in order: a test's (its columns but :data:`NOT_LISTED`:
#: :data:`~edc_bench.history.schema.COLUMNS`), how often it was indexed again with other content, and its row's chain
#: hash (what a customer's report prints). Computed from the fields: this module needs no database library.
LIST_COLUMNS = tuple(f.name for f in dataclasses.fields(TestRow) if f.name not in (*NOT_LISTED, "first_id"))


@dataclass(frozen=True, kw_only=True, slots=True)
class TeardownRow(_Columns):
    """What a valve's teardown found (table ``teardowns``)."""

    id: int
    valve_id: str
    finding: str
    clearance_mm: float | None = None
    note: str
    labelled_by: str
    labelled_at: str
    recorded_at: str
    #: the finding this one replaces
    corrects_id: int | None = None
    db_login: str | None = None
    recorded_by: str | None = None
    prev_hash: str | None = None
    row_hash: str | None = None


@dataclass(frozen=True, slots=True)
class TeardownMatch:
    """A teardown finding and the test it labels: the valve's last trustworthy test before it (None: no such test;
    :meth:`~edc_bench.history.store.HistoryStore.labelled_tests`)."""

    teardown: TeardownRow
    test: TestRow | None

    @property
    def label(self) -> int:
        """The class the finding teaches the classifier (1: the valve must be replaced)."""
        return FINDINGS[self.teardown.finding]

    def listed(self) -> dict[str, object]:
        """As ``label --list --json`` gives it: the test's columns (only ``valve_id`` without a test), and the
        finding's ``teardown_id``, ``finding``, ``label``, ``teardown_clearance_mm``, ``labelled_by``,
        ``labelled_at`` and ``note``."""
        f = self.teardown
        test = ({k: v for k, v in self.test.listed().items() if k not in ("changes", "chain_hash")}
                if self.test is not None else {"valve_id": f.valve_id})
        return {**test, "teardown_id": f.id, "finding": f.finding, "label": self.label,
                "teardown_clearance_mm": f.clearance_mm, "labelled_by": f.labelled_by, "labelled_at": f.labelled_at,
                "note": f.note}


@dataclass(frozen=True, kw_only=True, slots=True)
class AdoptionRow(_Columns):
    """A model a station was given to judge with (table ``adoptions``)."""

    id: int
    station: str
    model_name: str
    model_sha256: str
    adopted_by: str
    adopted_at: str
    db_login: str | None = None
    #: what the adoption was decided on, as JSON (None: a model without a shop's evaluation)
    evaluation: str | None = None
    prev_hash: str | None = None
    row_hash: str | None = None


class _RigFigures:
    """A row holding the figures of the reference valve and the rig at rest
    (:data:`~edc_bench.history.schema.FIGURES`)."""

    __slots__ = ()

    lvdt_zero_mm: float | None
    current_zero_a: float | None
    coil_r20_ohm: float | None
    a0_v_per_mm: float | None
    af_v: float | None
    a1_v_s_per_mm: float | None

    def figures(self) -> dict[str, float | None]:
        """The figures by name, in :data:`~edc_bench.history.schema.FIGURES`'s order."""
        return {"lvdt_zero_mm": self.lvdt_zero_mm, "current_zero_a": self.current_zero_a,
                "coil_r20_ohm": self.coil_r20_ohm, "a0_v_per_mm": self.a0_v_per_mm, "af_v": self.af_v,
                "a1_v_s_per_mm": self.a1_v_s_per_mm}


@dataclass(frozen=True, kw_only=True, slots=True)
class ReferenceRow(_RigFigures, _Columns):
    """A station's reference valve as registered, with its figures then (table ``reference_valves``)."""

    id: int
    station: str
    valve_id: str
    variant: str
    lvdt_zero_mm: float | None = None
    current_zero_a: float | None = None
    coil_r20_ohm: float | None = None
    a0_v_per_mm: float | None = None
    af_v: float | None = None
    a1_v_s_per_mm: float | None = None
    lvdt_at_floor: bool | None = None
    coil_temp_c: float | None = None
    simulated: bool
    #: the simulated valve (None on a rig)
    valve_spec: str | None = None
    #: how it was measured, as JSON
    details: str | None = None
    software_version: str
    registered_by: str
    registered_at: str
    db_login: str | None = None
    prev_hash: str | None = None
    row_hash: str | None = None


@dataclass(frozen=True, kw_only=True, slots=True)
class RigCheckRow(_RigFigures, _Columns):
    """One rig self-check, or a due check the technician skipped (table ``rig_checks``)."""

    id: int
    station: str
    #: the registration compared with
    reference_id: int
    #: GO, NO-GO or SKIPPED
    verdict: str
    #: the drifts named, comma-separated ('' for GO)
    causes: str
    #: the line the technician read
    words: str
    lvdt_zero_mm: float | None = None
    current_zero_a: float | None = None
    coil_r20_ohm: float | None = None
    a0_v_per_mm: float | None = None
    af_v: float | None = None
    a1_v_s_per_mm: float | None = None
    lvdt_at_floor: bool | None = None
    coil_temp_c: float | None = None
    simulated: bool
    #: every figure's drift and tolerance, how it was measured, as JSON
    details: str | None = None
    software_version: str
    checked_by: str
    checked_at: str
    db_login: str | None = None
    prev_hash: str | None = None
    row_hash: str | None = None


@dataclass(frozen=True, kw_only=True, slots=True)
class LoginRow(_Columns):
    """Which station (and person, and shop) a database login is (table ``edc_logins``)."""

    id: int
    login: str
    station: str | None = None
    person: str | None = None
    shop: str | None = None
    mapped_by: str
    mapped_at: str


@dataclass(frozen=True, kw_only=True, slots=True)
class GuardEventRow(_Columns):
    """What the history's guard found and did (table ``guard_events``)."""

    id: int
    event: str
    detail: str
    happened_at: str
    db_login: str | None = None
    prev_hash: str | None = None
    row_hash: str | None = None


@dataclass(frozen=True, kw_only=True, slots=True)
class AuditEvent:
    """One line of a valve's audit trail (:func:`~edc_bench.history.store.audit_events`)."""

    when: str
    event: str
    #: the row's id in its table
    id: int
    what: str
    by: str
    db_login: str | None
    chain_hash: str | None


@dataclass(frozen=True, slots=True)
class ChainHead:
    """A chain's last row, as a shop keeps it outside the station (``history --heads``)."""

    table: str
    chain: str
    id: int
    row_hash: str


__all__ = ["FINDINGS", "LIST_COLUMNS", "NOT_LISTED", "TEST_ROW_EXTRAS", "AdoptionRow", "AuditEvent", "ChainHead", "GuardEventRow", "LoginRow",
           "ReferenceRow", "RigCheckRow", "TeardownMatch", "TeardownRow", "TestRow"]
