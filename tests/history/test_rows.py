"""The history's typed rows (edc_bench/history/rows.py) hold their tables' columns, in order: a column added to a
table (edc_bench/history/schema.py) without its row's field fails here, naming it."""

from __future__ import annotations

import dataclasses

import pytest
import sqlalchemy as sa

from edc_bench.history import schema
from edc_bench.history.rows import (
    LIST_COLUMNS,
    TEST_ROW_EXTRAS,
    AdoptionRow,
    GuardEventRow,
    LoginRow,
    ReferenceRow,
    RigCheckRow,
    TeardownRow,
    TestRow,
)

ROWS = [(TestRow, schema.tests), (TeardownRow, schema.teardowns), (AdoptionRow, schema.adoptions),
        (LoginRow, schema.edc_logins), (GuardEventRow, schema.guard_events), (ReferenceRow, schema.reference_valves),
        (RigCheckRow, schema.rig_checks)]


@pytest.mark.parametrize("row_type, table", ROWS, ids=[t.name for _, t in ROWS])
def test_each_row_type_has_its_tables_columns_in_order_and_their_kinds(row_type: type, table: sa.Table) -> None:
    fields = [f for f in dataclasses.fields(row_type) if f.name not in TEST_ROW_EXTRAS]
    assert [f.name for f in fields] == [c.name for c in table.columns]
    kinds = {sa.Float: "float", sa.Boolean: "bool", sa.Integer: "int", sa.String: "str"}
    for f, column in zip(fields, table.columns, strict=True):
        kind = next(name for sql, name in kinds.items() if isinstance(column.type, sql))
        assert str(f.type).split(" | ")[0] == kind, (f.name, f.type, column.type)
        # a column the database may leave empty is optional in its row
        assert ("None" in str(f.type)) == bool(column.nullable and not column.primary_key), (f.name, f.type)


def test_a_row_is_built_from_a_querys_mapping_leaving_out_what_it_does_not_know() -> None:
    row = TeardownRow.of({"id": 3, "valve_id": "V1", "finding": "worn", "note": "", "labelled_by": "ana",
                          "labelled_at": "2026-05-02", "recorded_at": "2026-05-02", "withdrawn_row": True})
    assert row.id == 3 and row.corrects_id is None and "withdrawn_row" not in row.columns()
    with pytest.raises(dataclasses.FrozenInstanceError):
        row.finding = "reusable"  # type: ignore[misc]


def test_a_listing_gives_a_tests_columns_then_its_changes_and_chain_hash() -> None:
    assert LIST_COLUMNS == (*schema.COLUMNS, "changes", "chain_hash")


def test_a_rig_rows_figures_are_the_tables_figures_in_order() -> None:
    row = RigCheckRow(id=1, station="s", reference_id=1, verdict="GO", causes="", words="", simulated=True,
                      software_version="0.1.0", checked_by="ana", checked_at="2026-11-29T08:00:00+00:00", af_v=0.07)
    assert tuple(row.figures()) == schema.FIGURES and row.figures()["af_v"] == 0.07
