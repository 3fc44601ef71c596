"""The chain's figures for a filter: tests per day and station, the verdict mix, the first-pass and MARGINAL rates,
INVALID tests by where they point, and the stations that went quiet.

Every figure is one aggregate query over the tests as they stand (each test's first indexing, withdrawn tests left
out: :func:`~edc_bench.history.store.standing_tests`), so a chain of a million tests is never read into Python.
``edc-bench history --summary`` prints these figures and the web view's chain page shows them: both call
:func:`chain_summary`, so the two cannot disagree.

- *first tests*: tests that repeat no other (a MARGINAL's retest is not a first test);
- *first-pass rate*: the share of first tests that were PASS;
- *MARGINAL rate*: the share of first tests that were MARGINAL (each calls for a retest), and the retests done;
- *quiet*: a station whose latest test is older than ``quiet_days`` before ``now`` (a self-check is no test: a
  station that only checks its rig has stopped testing).
"""

from __future__ import annotations

import datetime as dt
from collections import Counter
from dataclasses import dataclass

import sqlalchemy as sa

from edc_bench.history.day_counts import counted_from_counts, counted_from_rows, counts_answer
from edc_bench.history.schema import edc_logins, reference_valves, rig_checks, tests
from edc_bench.history.store import Filters, HistoryStore, filter_clauses, station_shops
from edc_bench.verdict.verdicts import Verdict

#: A station with no test for this many days is listed as quiet.
QUIET_DAYS = 7

#: Stations asked for their latest test in one query (SQLite's compound SELECT holds at most 500).
STATIONS_PER_QUERY = 400

#: A range of more days is counted by month (a year's chart is twelve bars, not 365 a station).
DAILY_UP_TO_DAYS = 92

#: the area an INVALID row indexed before revision 0007 has: its record was not read again
NOT_RECORDED = "not recorded"


@dataclass(frozen=True)
class DayCount:
    """Tests of one station on one day, or in one month (``2026-11``) for a long range (the day as the test's start
    time writes it: UTC)."""

    day: str
    station: str
    tests: int


@dataclass(frozen=True)
class StationActivity:
    """A station's tests in the filter, its latest test and self-check (ISO times, UTC; None: never), and whether it
    went quiet (no test for :data:`QUIET_DAYS`)."""

    station: str
    tests: int
    last_test_at: str | None
    last_check_at: str | None
    quiet: bool
    #: the shop the station belongs to (None: no login mapping names one)
    shop: str | None = None


@dataclass(frozen=True)
class ChainSummary:
    """The chain's figures for one filter (:func:`chain_summary`)."""

    tests: int
    verdicts: tuple[tuple[str, int], ...]
    first_tests: int
    first_pass: int
    first_marginal: int
    retests: int
    invalid_areas: tuple[tuple[str, int], ...]
    per_day: tuple[DayCount, ...]
    stations: tuple[StationActivity, ...]
    #: what per_day counts by: ``day``, or ``month`` for a range of more than :data:`DAILY_UP_TO_DAYS` days
    period: str = "day"

    @property
    def first_pass_rate(self) -> float | None:
        """PASS among first tests (None: no first test)."""
        return self.first_pass / self.first_tests if self.first_tests else None

    @property
    def marginal_rate(self) -> float | None:
        """MARGINAL among first tests (None: no first test)."""
        return self.first_marginal / self.first_tests if self.first_tests else None

    @property
    def shops(self) -> tuple[tuple[str, int, int], ...]:
        """Each shop named (by name): its stations and their tests in the filter; stations of no shop left out."""
        stations: Counter[str] = Counter()
        counted: Counter[str] = Counter()
        for station in self.stations:
            if station.shop is not None:
                stations[station.shop] += 1
                counted[station.shop] += station.tests
        return tuple((shop, stations[shop], counted[shop]) for shop in sorted(stations))

    def count(self, verdict: str) -> int:
        """How many tests had ``verdict``."""
        return dict(self.verdicts).get(verdict, 0)


def chain_summary(store: HistoryStore, filters: Filters, now: dt.datetime | None = None,
                  quiet_days: int = QUIET_DAYS) -> ChainSummary:
    """The chain's figures for ``filters`` (see the module's docstring).

    The tests the filter selects counted by day, station, verdict, first test or retest and INVALID area
    (:mod:`~edc_bench.history.day_counts`: PostgreSQL's counts where they answer the filter, else the rows),
    summed in the database by day (month, for a long range) and station and by verdict; and each station's latest
    test from the (station, started_at) index.

    Parameters
    ----------
    store : HistoryStore
        The history (a station's SQLite or the chain's PostgreSQL).
    filters : Filters
        Which tests count (dates as UTC bounds, as :meth:`HistoryStore.list` takes them).
    now : datetime, optional
        The time quiet stations are judged at (default: now).
    quiet_days : int
        Days without a test after which a station is quiet.
    """
    period = counting_period(filters, now)
    use_counts = not store.is_sqlite and counts_answer(filters, period)
    counted = (counted_from_counts(filters, period) if use_counts else counted_from_rows(filters)).subquery("counted")
    when = counted.c.day if period == "day" else sa.func.substr(counted.c.day, 1, 7)
    keyed = sa.select(when.label("period"), *(counted.c[name] for name in ("station", "verdict", "first_test",
                                                                           "invalid_area", "tests"))).subquery("keyed")
    k = keyed.c
    # summed in the database: the days (or months) by station, and the verdict mix by first test and INVALID area
    # (a year's counts are a few hundred thousand; what comes back is a row per month and station, and a few)
    if store.is_sqlite:  # no grouping sets: two sums (a station's file is small)
        per_day = sa.select(sa.literal("day").label("kind"), k.period, k.station,
                            sa.cast(sa.null(), sa.String).label("verdict"), sa.cast(sa.null(), sa.Boolean).label("f"),
                            sa.cast(sa.null(), sa.String).label("area"), sa.func.sum(k.tests)).group_by(k.period,
                                                                                                         k.station)
        mix = sa.select(sa.literal("mix").label("kind"), sa.cast(sa.null(), sa.String).label("period"),
                        sa.cast(sa.null(), sa.String).label("station"), k.verdict, k.first_test, k.invalid_area,
                        sa.func.sum(k.tests)).group_by(k.verdict, k.first_test, k.invalid_area)
        sums: sa.Executable = sa.union_all(per_day, mix)
    else:  # one pass over the counts (or rows), both sums at once
        sums = (sa.select(sa.case((sa.func.grouping(k.period) == 0, "day"), else_="mix"), k.period, k.station,
                          k.verdict, k.first_test, k.invalid_area, sa.func.sum(k.tests))
                .group_by(sa.func.grouping_sets(sa.tuple_(k.period, k.station),
                                                sa.tuple_(k.verdict, k.first_test, k.invalid_area))))
    verdicts: Counter[str] = Counter()
    areas: Counter[str] = Counter()
    days: Counter[tuple[str, str]] = Counter()
    first_tests = first_pass = first_marginal = retests = 0
    with store.reading() as conn:
        if not store.is_sqlite:  # the sums hashed in memory, not sorted on disk: PostgreSQL's 4 MB default sorted a
            conn.exec_driver_sql("SET LOCAL work_mem = '32MB'")  # year's counts twice (0.25 s of 0.35, measured)
        for kind, when, station, verdict, is_first, area, total in conn.execute(sums):
            count = int(total or 0)
            if not count:  # a day whose tests were all withdrawn
                continue
            if kind == "day":
                days[(str(when), str(station))] += count
                continue
            verdicts[str(verdict)] += count
            if verdict == Verdict.INVALID:
                areas[str(area or NOT_RECORDED)] += count
            if is_first:
                first_tests += count
                first_pass += count if verdict == Verdict.PASS else 0
                first_marginal += count if verdict == Verdict.MARGINAL else 0
            else:
                retests += count
        per_station: Counter[str] = Counter()
        for (_, station), count in days.items():
            per_station[station] += count
        stations = _stations(conn, filters, per_station, now or dt.datetime.now(dt.UTC), quiet_days)
    return ChainSummary(sum(verdicts.values()), _ranked(verdicts), first_tests, first_pass, first_marginal, retests,
                        _ranked(areas), tuple(DayCount(d, s, n) for (d, s), n in sorted(days.items())), stations,
                        period)


def counting_period(filters: Filters, now: dt.datetime | None = None) -> str:
    """``day`` for a range of at most :data:`DAILY_UP_TO_DAYS` days, else ``month`` (all time included)."""
    if filters.since is None:
        return "month"
    until = (filters.until or (now or dt.datetime.now(dt.UTC)).date().isoformat())[:10]
    days = (dt.date.fromisoformat(until) - dt.date.fromisoformat(filters.since[:10])).days
    return "day" if days <= DAILY_UP_TO_DAYS else "month"


def _ranked(counts: Counter[str]) -> tuple[tuple[str, int], ...]:
    """Most first; a tie by name."""
    return tuple(sorted(counts.items(), key=lambda item: (-item[1], item[0])))


def _stations(conn: sa.Connection, filters: Filters, in_filter: Counter[str], now: dt.datetime, quiet_days: int
              ) -> tuple[StationActivity, ...]:
    """The stations the history knows (by the filter's tests, self-checks, registrations, or a login mapped to
    them), each with its latest test and self-check, whatever the dates asked (a station quiet this week is quiet
    whatever was asked), and its tests in the filter."""
    known = set(in_filter)
    for table in (rig_checks, reference_valves, edc_logins):
        query = sa.select(table.c.station).distinct().where(table.c.station.is_not(None))
        known |= {str(s) for (s,) in conn.execute(query)}
    shop_of = {str(station): str(shop) for station, shop in conn.execute(sa.select(station_shops()))}
    known |= set(shop_of)
    if filters.station is not None:
        known &= {filters.station}
    if filters.shop is not None:
        known = {station for station in known if shop_of.get(station) == filters.shop}
    wanted = filter_clauses(Filters(simulated=filters.simulated))
    cutoff = (now - dt.timedelta(days=quiet_days)).astimezone(dt.UTC).isoformat(timespec="seconds")
    if not known:
        return ()
    # each station's latest test and self-check read from an index (station, started_at; station), a query per
    # STATIONS_PER_QUERY stations (SQLite joins at most 500 SELECTs in one compound). A withdrawn test counts here:
    # it does not count in the figures, but the station ran it, so it was not quiet

    ordered = sorted(known)
    out = []
    for start in range(0, len(ordered), STATIONS_PER_QUERY):
        part = ordered[start:start + STATIONS_PER_QUERY]
        names = sa.union_all(*(sa.select(sa.literal(s, sa.String).label("station")) for s in part)).subquery()
        latest_test = (sa.select(sa.func.max(tests.c.started_at))
                       .where(tests.c.station == names.c.station, *wanted).scalar_subquery())
        latest_check = (sa.select(sa.func.max(rig_checks.c.checked_at))
                        .where(rig_checks.c.station == names.c.station).scalar_subquery())
        for station, last_test, last_check in conn.execute(sa.select(names.c.station, latest_test, latest_check)
                                                           .order_by(names.c.station)):
            out.append(StationActivity(str(station), int(in_filter.get(station, 0)),
                                       None if last_test is None else str(last_test),
                                       None if last_check is None else str(last_check),
                                       quiet=last_test is None or str(last_test) < cutoff,
                                       shop=shop_of.get(station)))
    return tuple(sorted(out, key=lambda activity: activity.station))  # one order, however many queries
