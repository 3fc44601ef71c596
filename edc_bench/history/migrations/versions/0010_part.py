"""A test names the part at fault: the valve, the control rack or the rack-travel sensor (#67).

- tests.part: the part diagnosis's part (edc_bench.verdict.part_sections.Part: "none", "valve or rack", "rack",
  "rack-travel sensor"); None in rows indexed before, whose records judged the valve alone (shown as "valve only
  judged"; their records are not read again).

Adding a nullable column changes no stored row's hash: a row's content is hashed without its empty values
(edc_bench.history.chain.canonical, and PostgreSQL's trigger strips nulls alike).

Revision ID: 0010
Revises: 0009
Create Date: 2026-12-01
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0010"
down_revision = "0009"
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.add_column("tests", sa.Column("part", sa.String(30)))


def downgrade() -> None:
    op.drop_column("tests", "part")
