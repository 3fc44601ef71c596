"""The chain's tests counted by day, station, verdict, first test or retest, INVALID area and simulated or not: the
rows every figure of :mod:`edc_bench.history.summary` is summed from.

Two sources give the same counts for a filter:

- :func:`counted_from_rows`: the test rows themselves (the tests as they stand, any filter);
- :func:`counted_from_day_counts`: PostgreSQL's ``test_day_counts`` (revision 0008: a trigger counts every first
  indexing), less the withdrawn tests' rows, for filters it can answer (:func:`day_counts_answer`: no valve,
  pump, pump type or technician asked); a range's first and last day, when they are not whole UTC days (a local
  day), are read from the rows. A year of a hundred stations is a few hundred thousand counts, not a million rows.

:func:`recount` counts the rows again as the trigger would have (``history --verify`` compares; the bulk
benchmark chain fills the counts with it).
"""

from __future__ import annotations

import datetime as dt
from dataclasses import replace
from typing import Any

import sqlalchemy as sa

from edc_bench.history.schema import test_day_counts, tests
from edc_bench.history.store import (Filters, filter_clauses, first_indexings, shop_stations, standing_tests,
                                     withdrawn_tests)

#: The count's key, in order: names and the expressions on a test row (revision 0008's trigger uses the same).
KEY = ("day", "station", "verdict", "first_test", "invalid_area", "simulated")


def _row_key() -> list[sa.ColumnElement[Any]]:
    """The key of a test row (as revision 0008's trigger computes it)."""
    return [sa.func.substr(tests.c.started_at, 1, 10).label("day"), tests.c.station.label("station"),
            tests.c.verdict.label("verdict"), tests.c.retest_of.is_(None).label("first_test"),
            sa.func.coalesce(tests.c.invalid_area, "").label("invalid_area"),
            sa.func.coalesce(tests.c.simulated, sa.false()).label("simulated")]


def day_counts_answer(filters: Filters) -> bool:
    """Whether the day counts can answer ``filters``: no valve, pump, pump type or technician asked (the days at
    either end of a range given to the second are read from the rows)."""
    return all(value is None for value in (filters.valve_id, filters.pump_serial, filters.variant, filters.operator))


def counted_from_rows(filters: Filters) -> sa.Select[Any]:
    """The counts (:data:`KEY` and ``tests``) of the tests as they stand that ``filters`` selects, from the rows."""
    key = _row_key()
    return (sa.select(*key, sa.func.count().label("tests")).where(standing_tests(), *filter_clauses(filters))
            .group_by(*key))


_DAY_START, _DAY_END = "T00:00:00+00:00", "T23:59:59+00:00"


def _next_day(day: str) -> str:
    return (dt.date.fromisoformat(day) + dt.timedelta(days=1)).isoformat()


def _whole_days(filters: Filters) -> tuple[str | None, str | None, list[Filters]]:
    """The whole UTC days ``filters`` spans (first, last; None: open) and the filters of its partial days at either
    end (a local day's bounds are UTC times of day), read from the rows. The same string comparisons as
    :func:`~edc_bench.history.store.filter_clauses`: the parts add up to what the rows give."""
    first, last, partial = filters.since, filters.until, []
    if filters.since is not None and "T" in filters.since and filters.since[10:] != _DAY_START:
        first = _next_day(filters.since[:10])  # the first day's tests from since on: from the rows
        partial.append(replace(filters, until=min(filters.until or "~", filters.since[:10] + "T99")))
    elif first is not None:
        first = first[:10]
    if filters.until is not None and "T" in filters.until and filters.until[10:] != _DAY_END:
        last = (dt.date.fromisoformat(filters.until[:10]) - dt.timedelta(days=1)).isoformat()
        partial.append(replace(filters, since=max(filters.since or "", filters.until[:10])))
    elif last is not None:
        last = last[:10]
    return first, last, partial


def counted_from_day_counts(filters: Filters) -> sa.Select[Any] | sa.CompoundSelect:
    """The same counts as :func:`counted_from_rows` for a filter :func:`day_counts_answer` accepts (PostgreSQL at
    revision 0008 or later), as rows whose sums by key are the counts: the kept counts of the whole days, the
    withdrawn tests' first rows counted negative, and the partial days at either end from the rows."""
    if not day_counts_answer(filters):
        raise ValueError("the day counts answer no valve, pump, pump type or technician")
    first, last, partial = _whole_days(filters)
    if first is not None and last is not None and first > last:  # within one or two days: the rows
        return counted_from_rows(filters)
    c = test_day_counts.c
    wanted: list[sa.ColumnElement[bool]] = []
    if filters.station is not None:
        wanted.append(c.station == filters.station)
    if filters.shop is not None:
        wanted.append(c.station.in_(shop_stations(filters.shop)))
    if filters.verdict is not None:
        wanted.append(c.verdict == filters.verdict)
    if filters.simulated is not None:
        wanted.append(c.simulated.is_(filters.simulated))
    if first is not None:
        wanted.append(c.day >= first)
    if last is not None:
        wanted.append(c.day <= last)
    whole = replace(filters, since=first, until=last)
    kept = sa.select(*(c[name] for name in KEY), c.tests.label("tests")).where(*wanted)
    key = _row_key()
    withdrawn = (sa.select(*key, (-sa.func.count()).label("tests"))
                 .where(first_indexings(), withdrawn_tests(), *filter_clauses(whole)).group_by(*key))
    # not summed by key here: the figures sum these rows by what they show (a key may come two or three times)
    return sa.union_all(kept, withdrawn, *(counted_from_rows(part) for part in partial))


def recount() -> sa.Select[Any]:
    """Every first indexing counted by :data:`KEY`, withdrawn or not: what ``test_day_counts`` holds when right."""
    key = _row_key()
    return sa.select(*key, sa.func.count().label("tests")).where(first_indexings()).group_by(*key)


def mismatches(conn: sa.Connection) -> list[str]:
    """Where ``test_day_counts`` is not the rows counted again (one line each; [] where it is, or on SQLite)."""
    if conn.dialect.name != "postgresql":
        return []
    kept = {tuple(row[:-1]): int(row[-1]) for row in conn.execute(sa.select(*(test_day_counts.c[n] for n in KEY),
                                                                            test_day_counts.c.tests))}
    counted = {tuple(row[:-1]): int(row[-1]) for row in conn.execute(recount())}
    lines = []
    for key in sorted(set(kept) | set(counted), key=lambda k: tuple(str(v) for v in k)):
        if kept.get(key, 0) != counted.get(key, 0):
            day, station, verdict, first, area, simulated = key
            lines.append(f"the day count of {station} on {day} ({verdict}{', retest' if not first else ''}"
                         f"{', ' + area if area else ''}{', simulated' if simulated else ''}) is "
                         f"{kept.get(key, 0)}, the rows count {counted.get(key, 0)}: the chain page's figures would "
                         "be wrong (the counts were written outside edc-bench)")
    return lines


__all__ = ["KEY", "counted_from_day_counts", "counted_from_rows", "day_counts_answer", "mismatches", "recount"]
