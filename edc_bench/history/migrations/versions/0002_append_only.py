"""Append-only: a stored row is never changed; corrections, withdrawals and adoptions are rows of their own.

- tests: a record folder indexed again adds a row (the unique folder goes); each row keeps the SHA-256 of
  record.json as read, its integrity manifest, when, by whom and as which database login it was indexed.
- teardowns: a finding may name the finding it corrects; the database login that wrote it.
- amendments (withdrawals of a test or a finding, with why) and adoptions (the model a station judges with).
- Triggers refuse UPDATE and DELETE (and TRUNCATE on PostgreSQL) on all four, for every login.

Revision ID: 0002
Revises: 0001
Create Date: 2026-11-26
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0002"
down_revision = "0001"
branch_labels = None
depends_on = None

TABLES = ("tests", "teardowns", "amendments", "adoptions")


def _tests_as_0001_without_unique() -> sa.Table:
    """The tests table as revision 0001 left it, but record_dir not unique (what SQLite's copy is made from)."""
    inspector = sa.inspect(op.get_bind())
    meta = sa.MetaData()
    columns = []
    for c in inspector.get_columns("tests"):
        columns.append(sa.Column(c["name"], c["type"], primary_key=c["name"] == "id", nullable=c["nullable"]))
    return sa.Table("tests", meta, *columns)


def upgrade() -> None:
    bind = op.get_bind()
    postgres = bind.dialect.name == "postgresql"
    new_test_columns = [sa.Column("record_sha256", sa.String(64)), sa.Column("record_manifest", sa.Text),
                        sa.Column("indexed_at", sa.String(40)), sa.Column("indexed_by", sa.String(200)),
                        sa.Column("db_login", sa.String(200))]
    if postgres:
        for constraint in sa.inspect(bind).get_unique_constraints("tests"):
            if constraint["column_names"] == ["record_dir"]:
                op.drop_constraint(constraint["name"], "tests", type_="unique")
        for column in new_test_columns:
            op.add_column("tests", column)
    else:  # SQLite drops a constraint by copying the table
        with op.batch_alter_table("tests", recreate="always", copy_from=_tests_as_0001_without_unique()) as batch:
            for column in new_test_columns:
                batch.add_column(column)
    for name in ("started_at", "valve_id", "pump_serial", "record_dir"):
        op.create_index(f"ix_tests_{name}", "tests", [name], if_not_exists=True)
    op.add_column("teardowns", sa.Column("corrects_id", sa.Integer))
    op.add_column("teardowns", sa.Column("db_login", sa.String(200)))
    op.create_index("ix_teardowns_valve_id", "teardowns", ["valve_id"], if_not_exists=True)
    op.create_table(
        "amendments",
        sa.Column("id", sa.Integer, primary_key=True, autoincrement=True),
        sa.Column("target", sa.String(20), nullable=False),
        sa.Column("target_id", sa.Integer, nullable=False),
        sa.Column("action", sa.String(20), nullable=False),
        sa.Column("reason", sa.Text, nullable=False),
        sa.Column("amended_by", sa.String(200), nullable=False),
        sa.Column("amended_at", sa.String(40), nullable=False),
        sa.Column("db_login", sa.String(200)),
    )
    op.create_table(
        "adoptions",
        sa.Column("id", sa.Integer, primary_key=True, autoincrement=True),
        sa.Column("station", sa.String(200), nullable=False),
        sa.Column("model_name", sa.String(200), nullable=False),
        sa.Column("model_sha256", sa.String(64), nullable=False),
        sa.Column("adopted_by", sa.String(200), nullable=False),
        sa.Column("adopted_at", sa.String(40), nullable=False),
        sa.Column("db_login", sa.String(200)),
    )
    if postgres:
        # '%%': the driver takes '%' for a parameter; PostgreSQL's RAISE gets '%', its own placeholder
        bind.exec_driver_sql(
            "CREATE OR REPLACE FUNCTION edc_bench_append_only() RETURNS trigger LANGUAGE plpgsql AS $$ BEGIN "
            "RAISE EXCEPTION 'edc-bench history is append-only: %% on table %% refused; add a correction or a "
            "withdrawal instead', TG_OP, TG_TABLE_NAME USING ERRCODE = 'raise_exception'; END $$")
        for table in TABLES:
            bind.exec_driver_sql(f"CREATE TRIGGER {table}_append_only BEFORE UPDATE OR DELETE ON {table} "
                                 "FOR EACH ROW EXECUTE FUNCTION edc_bench_append_only()")
            bind.exec_driver_sql(f"CREATE TRIGGER {table}_no_truncate BEFORE TRUNCATE ON {table} "
                                 "FOR EACH STATEMENT EXECUTE FUNCTION edc_bench_append_only()")
    else:
        for table in TABLES:
            for event in ("UPDATE", "DELETE"):
                bind.exec_driver_sql(
                    f"CREATE TRIGGER {table}_no_{event.lower()} BEFORE {event} ON {table} BEGIN "
                    f"SELECT RAISE(ABORT, 'edc-bench history is append-only: {event} on table {table} refused; "
                    "add a correction or a withdrawal instead'); END")
