"""The history as edc-bench kept it before its schema had revisions: tests (one row per record folder) and teardowns.

A history made by an older edc-bench has these tables, perhaps without the columns added since (it added them
on open); this revision makes what is missing and leaves what is there, so every older history arrives at the
same place.

Revision ID: 0001
Revises:
Create Date: 2026-11-26
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0001"
down_revision = None
branch_labels = None
depends_on = None


def _tests_columns() -> list[sa.Column]:
    return [
        sa.Column("id", sa.Integer, primary_key=True, autoincrement=True),
        sa.Column("record_dir", sa.String(1024), nullable=False, unique=True),
        sa.Column("started_at", sa.String(40), nullable=False, index=True),
        sa.Column("valve_id", sa.String(200), nullable=False, index=True),
        sa.Column("pump_serial", sa.String(200), nullable=False, index=True),
        sa.Column("variant", sa.String(200), nullable=False),
        sa.Column("part_number", sa.String(100), nullable=False),
        sa.Column("verdict", sa.String(20), nullable=False),
        sa.Column("af_v", sa.Float),
        sa.Column("a1_v_s_per_mm", sa.Float),
        sa.Column("af_rel", sa.Float),
        sa.Column("a1_rel", sa.Float),
        sa.Column("probability_faulty", sa.Float),
        sa.Column("distance", sa.Float),
        sa.Column("station", sa.String(200), nullable=False),
        sa.Column("operator", sa.String(200), nullable=False),
        sa.Column("clock", sa.String(20), nullable=False),
        sa.Column("software_version", sa.String(40), nullable=False),
        sa.Column("reason", sa.Text, nullable=False),
        sa.Column("model_name", sa.String(200)),
        sa.Column("model_sha256", sa.String(64)),
        sa.Column("coil_r20_ohm", sa.Float),
        sa.Column("coil_in_spec", sa.Boolean),
        sa.Column("model_fits", sa.Boolean),
        sa.Column("stop_reason", sa.String(40)),
        sa.Column("test_s", sa.Float),
    ]


def _teardowns_columns() -> list[sa.Column]:
    return [
        sa.Column("id", sa.Integer, primary_key=True, autoincrement=True),
        sa.Column("valve_id", sa.String(200), nullable=False, index=True),
        sa.Column("finding", sa.String(20), nullable=False),
        sa.Column("clearance_mm", sa.Float),
        sa.Column("note", sa.Text, nullable=False),
        sa.Column("labelled_by", sa.String(200), nullable=False),
        sa.Column("labelled_at", sa.String(40), nullable=False),
        sa.Column("recorded_at", sa.String(40), nullable=False),
    ]


def upgrade() -> None:
    inspector = sa.inspect(op.get_bind())
    for name, columns in (("tests", _tests_columns()), ("teardowns", _teardowns_columns())):
        if not inspector.has_table(name):
            op.create_table(name, *columns)
            continue
        present = {c["name"] for c in inspector.get_columns(name)}
        for column in columns:  # columns an older edc-bench added later: empty in its rows
            if column.name not in present:
                op.add_column(name, sa.Column(column.name, column.type, nullable=True))
