"""An INVALID test says where to look (rig, mounting, bus, PC, calibration), and the chain's figures are indexed.

- tests.invalid_area: what an INVALID test points the technician at (edc_bench.records.advice.Area); None for every
  other verdict and in rows indexed before (their records are not read again: the web view counts them "not
  recorded").
- an index on (station, started_at): the chain's figures per station and day, and a station's latest test, are
  read from it instead of the whole table.

Adding a nullable column changes no stored row's hash: a row's content is hashed without its empty values
(edc_bench.history.chain.canonical, and PostgreSQL's trigger strips nulls alike).

Revision ID: 0007
Revises: 0006
Create Date: 2026-11-29
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0007"
down_revision = "0006"
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.add_column("tests", sa.Column("invalid_area", sa.String(20)))
    op.create_index("ix_tests_station_started_at", "tests", ["station", "started_at"])


def downgrade() -> None:
    op.drop_index("ix_tests_station_started_at", table_name="tests")
    op.drop_column("tests", "invalid_area")
