"""Each test row says whether it is its test's first indexing, and each station may be given its shop.

- tests.first_indexing: true when no row of the same test (test_key) was stored before this one, false for a
  test indexed again with other content (a change every reader shows); None in rows stored before this revision
  (readers ask the earlier rows, as before). "The tests as they stand" then reads only the rows a filter selects,
  not every row of the table. On PostgreSQL the insert trigger sets it (what a client sends is not trusted),
  after taking a transaction lock on the test's key, so two stations indexing one test at once cannot both be
  its first; on SQLite the program sets it inside its write lock. ``history --verify`` holds every row's value to
  the rows before it.
- test_day_counts (PostgreSQL): the tests that stand counted per day (UTC), station, verdict, first test or retest,
  INVALID area and simulated or not, kept by a trigger after each first indexing (and filled here from the rows
  there are): the chain's figures over months read these counts, not a million rows. Not a record: a count the
  database keeps of the records (no login may write it; ``history --verify`` counts again and compares).
  Withdrawals are subtracted where the counts are read (they are few).
- an index on (operator, started_at): a technician's tests over months, read from the index.
- edc_logins.shop: the shop a login's station belongs to (``history --map-login LOGIN --station S --shop SHOP``);
  the chain's figures are counted by shop from each station's newest mapping that names one.

Adding nullable columns changes no stored row's hash (empty values are left out of a row's content); a new row's
first_indexing is part of its content, so it is chained like the rest.

Revision ID: 0008
Revises: 0007
Create Date: 2026-11-29
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

import sqlalchemy as sa
from alembic import op

revision = "0008"
down_revision = "0007"
branch_labels = None
depends_on = None

#: Where 0006's stamp asks whether another station indexed the test first (its key set by then): the test's lock
#: and its first indexing go right before it, so that check too sees a row committed a moment ago by another station.
_BEFORE = "IF NOT trusted AND EXISTS (SELECT 1 FROM public.tests t WHERE (t.test_key"

_FIRST_INDEXING = (
    "PERFORM pg_catalog.pg_advisory_xact_lock(pg_catalog.hashtextextended(NEW.test_key, 8)); "
    "NEW.first_indexing := NOT EXISTS (SELECT 1 FROM public.tests t WHERE t.test_key = NEW.test_key); "
)


def _revision_0006():  # noqa: ANN202 - the module of revision 0006 (its file name is no module name)
    spec = importlib.util.spec_from_file_location("edc_bench_revision_0006", Path(__file__).with_name("0006_chain.py"))
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _tests_stamp(first_indexing: bool) -> str:
    """The tests' insert trigger function: 0006's, with the first-indexing statements if asked."""
    text = _revision_0006()._pg_stamp_function("tests")
    if first_indexing:
        assert text.count(_BEFORE) == 1, "revision 0006's stamp changed: place the first-indexing statements again"
        text = text.replace(_BEFORE, _FIRST_INDEXING + _BEFORE)
    return text.replace("%", "%%")


#: A standing test's place in the day counts (the same expressions fill them, count them again and read them).
DAY_COUNT_KEY = {"day": "substr({t}.started_at, 1, 10)", "station": "{t}.station", "verdict": "{t}.verdict",
                 "first_test": "({t}.retest_of IS NULL)", "invalid_area": "coalesce({t}.invalid_area, '')",
                 "simulated": "coalesce({t}.simulated, false)"}

_COUNT_FUNCTION = f"""
CREATE OR REPLACE FUNCTION public.edc_bench_count_test() RETURNS trigger LANGUAGE plpgsql SECURITY DEFINER
SET search_path = pg_catalog, public, pg_temp AS $fn$
BEGIN
    INSERT INTO public.test_day_counts ({", ".join(DAY_COUNT_KEY)}, tests)
        VALUES ({", ".join(expression.format(t="NEW") for expression in DAY_COUNT_KEY.values())}, 1)
        ON CONFLICT ({", ".join(DAY_COUNT_KEY)}) DO UPDATE SET tests = public.test_day_counts.tests + 1;
    RETURN NULL;
END $fn$"""


def upgrade() -> None:
    op.add_column("tests", sa.Column("first_indexing", sa.Boolean))
    op.add_column("edc_logins", sa.Column("shop", sa.String(200)))
    op.create_index("ix_tests_operator_started_at", "tests", ["operator", "started_at"])
    bind = op.get_bind()
    if bind.dialect.name != "postgresql":
        return
    bind.exec_driver_sql(_tests_stamp(first_indexing=True))
    op.create_table(
        "test_day_counts",
        sa.Column("day", sa.String(10), primary_key=True),
        sa.Column("station", sa.String(200), primary_key=True),
        sa.Column("verdict", sa.String(20), primary_key=True),
        sa.Column("first_test", sa.Boolean, primary_key=True),
        sa.Column("invalid_area", sa.String(20), primary_key=True),
        sa.Column("simulated", sa.Boolean, primary_key=True),
        sa.Column("tests", sa.BigInteger, nullable=False),
    )
    # the rows there are: each test's first row (no earlier row of its key), as readers took them before
    key = ", ".join(expression.format(t="t") for expression in DAY_COUNT_KEY.values())
    bind.exec_driver_sql(
        f"INSERT INTO test_day_counts ({', '.join(DAY_COUNT_KEY)}, tests) SELECT {key}, count(*) FROM tests t "
        "WHERE NOT EXISTS (SELECT 1 FROM tests e WHERE e.test_key = t.test_key AND e.id < t.id) "
        f"GROUP BY {key}")
    bind.exec_driver_sql(_COUNT_FUNCTION.replace("%", "%%"))
    bind.exec_driver_sql("CREATE TRIGGER tests_day_count AFTER INSERT ON tests FOR EACH ROW "
                         "WHEN (NEW.first_indexing) EXECUTE FUNCTION edc_bench_count_test()")


def downgrade() -> None:
    op.drop_index("ix_tests_operator_started_at", table_name="tests")
    if op.get_bind().dialect.name == "postgresql":
        op.get_bind().exec_driver_sql("DROP TRIGGER tests_day_count ON tests")
        op.get_bind().exec_driver_sql("DROP FUNCTION edc_bench_count_test()")
        op.drop_table("test_day_counts")
        op.get_bind().exec_driver_sql(_tests_stamp(first_indexing=False))
    op.drop_column("edc_logins", "shop")
    op.drop_column("tests", "first_indexing")
