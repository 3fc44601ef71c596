"""The tests counted per month beside the day counts, a pump type's tests read from an index, and an adoption's
evaluation.

- test_month_counts (PostgreSQL): the tests that stand counted per month (UTC), station, pump type (variant and
  part number), verdict, first test or retest, INVALID area and simulated or not, kept by the same trigger as the
  day counts (revision 0008) and filled here from the rows there are. A year of a hundred stations is a few tens of
  thousands of counts, not a quarter of a million day counts: the chain's figures over a year sum whole months
  from these, and the days of a partial month from the day counts. The pump type is in the key so that a pump
  type's year reads counts too. Not a record: no login writes it; ``history --verify`` counts again and compares.
- indexes on (variant, started_at) and (part_number, started_at): a pump type's tests in a partial month, read
  from an index (the filter matches either).
- adoptions.evaluation: what an adoption was decided on, a shop candidate's cross-validated figures beside the
  model it replaced (JSON, from the candidate's file), shown on the web view's models page. Rows adopted before
  have none. A nullable column changes no stored row's hash (empty values are left out of a row's content).

Revision ID: 0009
Revises: 0008
Create Date: 2026-11-29
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

import sqlalchemy as sa
from alembic import op

revision = "0009"
down_revision = "0008"
branch_labels = None
depends_on = None


def _revision_0008():  # noqa: ANN202 - the module of revision 0008 (its file name is no module name)
    spec = importlib.util.spec_from_file_location("edc_bench_revision_0008",
                                                  Path(__file__).with_name("0008_first_indexing.py"))
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


#: A standing test's place in the month counts (the same expressions fill them and count them again).
MONTH_COUNT_KEY = {"month": "substr({t}.started_at, 1, 7)", "station": "{t}.station", "variant": "{t}.variant",
                   "part_number": "{t}.part_number", "verdict": "{t}.verdict",
                   "first_test": "({t}.retest_of IS NULL)", "invalid_area": "coalesce({t}.invalid_area, '')",
                   "simulated": "coalesce({t}.simulated, false)"}


def _upsert(table: str, key: dict[str, str]) -> str:
    return (f"INSERT INTO public.{table} ({', '.join(key)}, tests) "
            f"VALUES ({', '.join(expression.format(t='NEW') for expression in key.values())}, 1) "
            f"ON CONFLICT ({', '.join(key)}) DO UPDATE SET tests = public.{table}.tests + 1;")


def _count_function() -> str:
    """Revision 0008's counting function, counting each first indexing by month as well as by day."""
    return f"""
CREATE OR REPLACE FUNCTION public.edc_bench_count_test() RETURNS trigger LANGUAGE plpgsql SECURITY DEFINER
SET search_path = pg_catalog, public, pg_temp AS $fn$
BEGIN
    {_upsert("test_day_counts", _revision_0008().DAY_COUNT_KEY)}
    {_upsert("test_month_counts", MONTH_COUNT_KEY)}
    RETURN NULL;
END $fn$"""


def upgrade() -> None:
    op.add_column("adoptions", sa.Column("evaluation", sa.Text))
    op.create_index("ix_tests_variant_started_at", "tests", ["variant", "started_at"])
    op.create_index("ix_tests_part_number_started_at", "tests", ["part_number", "started_at"])
    bind = op.get_bind()
    if bind.dialect.name != "postgresql":
        return
    op.create_table(
        "test_month_counts",
        sa.Column("month", sa.String(7), primary_key=True),
        sa.Column("station", sa.String(200), primary_key=True),
        sa.Column("variant", sa.String(200), primary_key=True),
        sa.Column("part_number", sa.String(100), primary_key=True),
        sa.Column("verdict", sa.String(20), primary_key=True),
        sa.Column("first_test", sa.Boolean, primary_key=True),
        sa.Column("invalid_area", sa.String(20), primary_key=True),
        sa.Column("simulated", sa.Boolean, primary_key=True),
        sa.Column("tests", sa.BigInteger, nullable=False),
    )
    # the same lock as the trigger's: no test is indexed between the filling and the function counting months
    bind.exec_driver_sql("LOCK TABLE tests IN SHARE ROW EXCLUSIVE MODE")
    key = ", ".join(expression.format(t="t") for expression in MONTH_COUNT_KEY.values())
    bind.exec_driver_sql(
        f"INSERT INTO test_month_counts ({', '.join(MONTH_COUNT_KEY)}, tests) SELECT {key}, count(*) FROM tests t "
        "WHERE t.first_indexing OR (t.first_indexing IS NULL AND "
        "NOT EXISTS (SELECT 1 FROM tests e WHERE e.test_key = t.test_key AND e.id < t.id)) "
        f"GROUP BY {key}")
    bind.exec_driver_sql(_count_function().replace("%", "%%"))


def downgrade() -> None:
    if op.get_bind().dialect.name == "postgresql":
        op.get_bind().exec_driver_sql(_revision_0008()._COUNT_FUNCTION.replace("%", "%%"))
        op.drop_table("test_month_counts")
    op.drop_index("ix_tests_part_number_started_at", table_name="tests")
    op.drop_index("ix_tests_variant_started_at", table_name="tests")
    op.drop_column("adoptions", "evaluation")
