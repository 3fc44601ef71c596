"""The rig self-check's ledger: reference valves registered, and every self-check with its figures (append-only).

- reference_valves: a station's reference valve and its figures when registered (a registration again is a new
  row; the newest of a station stands).
- rig_checks: each self-check: GO or NO-GO, the drifts named, its figures, and the registration compared with.
- Triggers refuse UPDATE and DELETE (and TRUNCATE on PostgreSQL) on both, as on the other tables.

Revision ID: 0005
Revises: 0004
Create Date: 2026-11-27
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0005"
down_revision = "0004"
branch_labels = None
depends_on = None

TABLES = ("reference_valves", "rig_checks")


def _figures() -> list[sa.Column]:
    """The figures of the reference valve and the rig at rest (edc_bench.selfcheck.compare.QUANTITIES)."""
    return [sa.Column(name, sa.Float) for name in ("lvdt_zero_mm", "current_zero_a", "coil_r20_ohm", "a0_v_per_mm",
                                                   "af_v", "a1_v_s_per_mm")] + [sa.Column("lvdt_at_floor", sa.Boolean)]


def upgrade() -> None:
    bind = op.get_bind()
    op.create_table(
        "reference_valves",
        sa.Column("id", sa.Integer, primary_key=True, autoincrement=True),
        sa.Column("station", sa.String(200), nullable=False, index=True),
        sa.Column("valve_id", sa.String(200), nullable=False),
        sa.Column("variant", sa.String(200), nullable=False),
        *_figures(),
        sa.Column("coil_temp_c", sa.Float),
        sa.Column("simulated", sa.Boolean, nullable=False),
        sa.Column("valve_spec", sa.String(200)),  # the simulated valve (None on a rig)
        sa.Column("details", sa.Text),  # JSON: how it was measured (seed, the rig's drift on the simulated rig...)
        sa.Column("software_version", sa.String(40), nullable=False),
        sa.Column("registered_by", sa.String(200), nullable=False),
        sa.Column("registered_at", sa.String(40), nullable=False),
        sa.Column("db_login", sa.String(200)),
    )
    op.create_table(
        "rig_checks",
        sa.Column("id", sa.Integer, primary_key=True, autoincrement=True),
        sa.Column("station", sa.String(200), nullable=False, index=True),
        sa.Column("reference_id", sa.Integer, nullable=False),  # the registration compared with
        sa.Column("verdict", sa.String(10), nullable=False),  # GO or NO-GO
        sa.Column("causes", sa.Text, nullable=False),  # the drifts named, comma-separated ('' for GO)
        sa.Column("words", sa.Text, nullable=False),  # the line the technician read
        *_figures(),
        sa.Column("coil_temp_c", sa.Float),
        sa.Column("simulated", sa.Boolean, nullable=False),
        sa.Column("details", sa.Text),  # JSON: every figure's drift and tolerance, how it was measured
        sa.Column("software_version", sa.String(40), nullable=False),
        sa.Column("checked_by", sa.String(200), nullable=False),
        sa.Column("checked_at", sa.String(40), nullable=False, index=True),
        sa.Column("db_login", sa.String(200)),
    )
    if bind.dialect.name == "postgresql":  # the function revision 0002 made
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
