"""Tests on the simulated rig marked: left out of trends and training unless asked for.

Revision ID: 0003
Revises: 0002
Create Date: 2026-11-26
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0003"
down_revision = "0002"
branch_labels = None
depends_on = None


def upgrade() -> None:
    # None in rows indexed before: counted as a rig's tests (a history kept before this held few simulated ones)
    op.add_column("tests", sa.Column("simulated", sa.Boolean))
