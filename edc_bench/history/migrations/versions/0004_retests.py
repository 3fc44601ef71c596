"""A retest names the test it repeats and what the two decided (the MARGINAL procedure).

Revision ID: 0004
Revises: 0003
Create Date: 2026-11-26
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0004"
down_revision = "0003"
branch_labels = None
depends_on = None


def upgrade() -> None:
    # None in rows indexed before, and in every test that repeats none
    op.add_column("tests", sa.Column("retest_of", sa.String(1024)))
    op.add_column("tests", sa.Column("decision", sa.String(20)))


def downgrade() -> None:
    op.drop_column("tests", "decision")
    op.drop_column("tests", "retest_of")
