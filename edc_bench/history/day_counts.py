"""The chain's tests counted by day (or month), station, verdict, first test or retest, INVALID area and simulated
or not: the rows every figure of :mod:`edc_bench.history.summary` is summed from.

Two sources give the same counts for a filter:

- :func:`counted_from_rows`: the test rows themselves (the tests as they stand, any filter);
- :func:`counted_from_counts`: PostgreSQL's counts, kept by a trigger that counts every first indexing, less the
  withdrawn tests' rows, for the filters they answer (:func:`counts_answer`: no valve, pump or technician asked):
  ``test_day_counts`` (revision 0008) by day, and for figures summed by month ``test_month_counts`` (revision
  0009, which knows the pump type too) for the whole months, the day counts for the days of a partial month. A
  range's first and last day, when they are not whole UTC days (a local day), are read from the rows, as are a
  pump type's days. A year of a hundred stations is some 65,000 month counts or 240,000 day counts, not a million
  rows.

:func:`recount` counts the rows again as the trigger would have (``history --verify`` compares; the bulk
benchmark chain fills the counts with it).
"""

from __future__ import annotations

import datetime as dt
from dataclasses import replace
from typing import Any

import sqlalchemy as sa

from edc_bench.history.schema import test_day_counts, test_month_counts, tests
from edc_bench.history.store import (Filters, filter_clauses, first_indexings, shop_stations, standing_tests,
                                     withdrawn_tests)

#: The count's key, in order: names and the expressions on a test row (revision 0008's trigger uses the same).
KEY = ("day", "station", "verdict", "first_test", "invalid_area", "simulated")
#: The month count's key (revision 0009's trigger uses the same): a pump type's figures over a year read it too.
MONTH_KEY = ("month", "station", "variant", "part_number", "verdict", "first_test", "invalid_area", "simulated")


def _row_key() -> list[sa.ColumnElement[Any]]:
    """The key of a test row (as revision 0008's trigger computes it)."""
    return [sa.func.substr(tests.c.started_at, 1, 10).label("day"), tests.c.station.label("station"),
            tests.c.verdict.label("verdict"), tests.c.retest_of.is_(None).label("first_test"),
            sa.func.coalesce(tests.c.invalid_area, "").label("invalid_area"),
            sa.func.coalesce(tests.c.simulated, sa.false()).label("simulated")]


def _month_row_key() -> list[sa.ColumnElement[Any]]:
    """The month key of a test row (as revision 0009's trigger computes it)."""
    day, station, *rest = _row_key()
    return [sa.func.substr(tests.c.started_at, 1, 7).label("month"), station, tests.c.variant.label("variant"),
            tests.c.part_number.label("part_number"), *rest]


def counts_answer(filters: Filters, period: str = "day") -> bool:
    """Whether the counts can answer ``filters`` summed by ``period`` (``day`` or ``month``): no valve, pump or
    technician asked, and no pump type unless by month (the month counts know it; the days of a partial month
    are then read from the rows, as are the days at either end of a range given to the second)."""
    return (all(value is None for value in (filters.valve_id, filters.pump_serial, filters.operator))
            and (filters.variant is None or period == "month"))


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


def _month_after(month: str) -> str:
    year, number = int(month[:4]), int(month[5:7])
    return f"{year + number // 12:04d}-{number % 12 + 1:02d}"


def _month_before(month: str) -> str:
    year, number = int(month[:4]), int(month[5:7])
    return f"{year - (number == 1):04d}-{(number - 2) % 12 + 1:02d}"


def _whole_months(first: str | None, last: str | None
                  ) -> tuple[tuple[str | None, str | None] | None, list[tuple[str | None, str | None]]]:
    """The whole months between the whole days ``first`` and ``last`` (each None: open), as (first month, last
    month; None: open) or None for no whole month, and the spans of days (first, last) left at either end."""
    since = None if first is None else (first[:7] if first[8:] == "01" else _month_after(first[:7]))
    until = None if last is None else (last[:7] if _next_day(last)[8:] == "01" else _month_before(last[:7]))
    if since is not None and until is not None and since > until:
        return None, [(first, last)]
    days: list[tuple[str | None, str | None]] = []
    if first is not None and since is not None and first < f"{since}-01":
        days.append((first, (dt.date.fromisoformat(f"{since}-01") - dt.timedelta(days=1)).isoformat()))
    if last is not None and until is not None and last > f"{until}-31":
        days.append((f"{_month_after(until)}-01", last))
    return (since, until), days


def _kept(table: sa.Table, when: str, filters: Filters, first: str | None, last: str | None) -> sa.Select[Any]:
    """The kept counts of ``table`` (by ``when``: day or month) from ``first`` to ``last`` that ``filters`` asks for
    (its dates aside), as rows of :data:`KEY` (a month count's ``day`` is its month)."""
    c = table.c
    wanted: list[sa.ColumnElement[bool]] = []
    if filters.station is not None:
        wanted.append(c.station == filters.station)
    if filters.shop is not None:
        wanted.append(c.station.in_(shop_stations(filters.shop)))
    if filters.verdict is not None:
        wanted.append(c.verdict == filters.verdict)
    if filters.simulated is not None:
        wanted.append(c.simulated.is_(filters.simulated))
    if filters.variant is not None:  # as filter_clauses asks: either name of the pump type
        wanted.append(sa.or_(c.variant == filters.variant, c.part_number == filters.variant))
    if first is not None:
        wanted.append(c[when] >= first)
    if last is not None:
        wanted.append(c[when] <= last)
    return sa.select(c[when].label("day"), *(c[name] for name in KEY[1:]), c.tests.label("tests")).where(*wanted)


def counted_from_counts(filters: Filters, period: str = "day") -> sa.Select[Any] | sa.CompoundSelect:
    """The same counts as :func:`counted_from_rows` for a filter :func:`counts_answer` accepts (PostgreSQL at
    revision 0009 or later), as rows whose sums by key are the counts: the kept counts, the withdrawn tests' first
    rows counted negative, and the partial days at either end from the rows.

    By ``month``, whole months are read from the month counts and a row's ``day`` is then its month (sum by the
    first seven characters); the days of a partial month come from the day counts (the rows, for a pump type).
    """
    if not counts_answer(filters, period):
        raise ValueError(f"the counts by {period} answer no valve, pump or technician, and a pump type by month only")
    first, last, partial = _whole_days(filters)
    if first is not None and last is not None and first > last:  # within one or two days: the rows
        return counted_from_rows(filters)
    if period == "month":
        months, day_spans = _whole_months(first, last)
    else:
        months, day_spans = None, [(first, last)]
    kept = [] if months is None else [_kept(test_month_counts, "month", filters, *months)]
    # the days the counts give (their withdrawn tests subtracted); the rest comes from the rows as they stand
    counted_days: tuple[str | None, str | None] | None = (first, last)
    for since, until in day_spans:
        if filters.variant is None:
            kept.append(_kept(test_day_counts, "day", filters, since, until))
        else:  # the day counts do not know the pump type
            partial.append(replace(filters, since=since, until=until))
    if filters.variant is not None:
        counted_days = None if months is None else (None if months[0] is None else f"{months[0]}-01",
                                                    None if months[1] is None else f"{months[1]}-31")
    parts: list[sa.Select[Any]] = [*kept, *(counted_from_rows(part) for part in partial)]
    if counted_days is not None:
        key = _row_key()
        since, until = counted_days
        parts.append(sa.select(*key, (-sa.func.count()).label("tests"))
                     .where(first_indexings(), withdrawn_tests(),
                            *filter_clauses(replace(filters, since=since, until=until)))
                     .group_by(*key))
    # not summed by key here: the figures sum these rows by what they show (a key may come two or three times)
    return sa.union_all(*parts)


def recount(period: str = "day") -> sa.Select[Any]:
    """Every first indexing counted by :data:`KEY` (``month``: by :data:`MONTH_KEY`), withdrawn or not: what
    ``test_day_counts`` (``test_month_counts``) holds when right."""
    key = _row_key() if period == "day" else _month_row_key()
    return sa.select(*key, sa.func.count().label("tests")).where(first_indexings()).group_by(*key)


def _differences(conn: sa.Connection, table: sa.Table, names: tuple[str, ...], period: str
                 ) -> list[tuple[tuple[Any, ...], int, int]]:
    """The keys whose kept count is not the rows counted again: (key, kept, counted)."""
    kept = {tuple(row[:-1]): int(row[-1]) for row in conn.execute(sa.select(*(table.c[n] for n in names),
                                                                            table.c.tests))}
    counted = {tuple(row[:-1]): int(row[-1]) for row in conn.execute(recount(period))}
    return [(key, kept.get(key, 0), counted.get(key, 0))
            for key in sorted(set(kept) | set(counted), key=lambda k: tuple(str(v) for v in k))
            if kept.get(key, 0) != counted.get(key, 0)]


def _what(verdict: str, first: bool, area: str, simulated: bool) -> str:
    return f"{verdict}{', retest' if not first else ''}{', ' + area if area else ''}{', simulated' if simulated else ''}"


_WRONG = "the chain page's figures would be wrong (the counts were written outside edc-bench)"


def mismatches(conn: sa.Connection) -> list[str]:
    """Where ``test_day_counts`` or ``test_month_counts`` is not the rows counted again (one line each; [] where
    they are, or on SQLite)."""
    if conn.dialect.name != "postgresql":
        return []
    lines = []
    for (day, station, *what), kept, counted in _differences(conn, test_day_counts, KEY, "day"):
        lines.append(f"the day count of {station} on {day} ({_what(*what)}) is {kept}, the rows count {counted}: "
                     + _WRONG)
    if sa.inspect(conn).has_table("test_month_counts"):
        for (month, station, variant, part, *what), kept, counted in _differences(conn, test_month_counts,
                                                                                  MONTH_KEY, "month"):
            lines.append(f"the month count of {station} in {month} ({variant} {part}, {_what(*what)}) is {kept}, "
                         f"the rows count {counted}: " + _WRONG)
    return lines


__all__ = ["KEY", "MONTH_KEY", "counted_from_counts", "counted_from_rows", "counts_answer", "mismatches", "recount"]
