"""PostgreSQL's day and month counts (revisions 0008, 0009) against the rows they count: kept by the trigger as
tests are indexed, re-indexed, repeated and withdrawn, they give the chain's figures the rows give, for every filter
the chain page reads them for (a local day's bounds, partial months and a pump type by either name included);
counts changed outside edc-bench are named by --verify."""

from __future__ import annotations

import datetime as dt
import uuid

import psycopg
import pytest
import sqlalchemy as sa
from helpers import edc_bench

from edc_bench.history.bulk_chain import fill_bulk_chain
from edc_bench.history.day_counts import counted_from_counts, counted_from_rows, mismatches
from edc_bench.history.store import Filters, HistoryStore
from edc_bench.history.summary import chain_summary


def _row(station: str, started: str, verdict: str, **more: object) -> dict:
    return {"record_dir": f"/records/{uuid.uuid4().hex}", "started_at": started, "valve_id": "V-1",
            "pump_serial": "P-1", "variant": "p-edc-default", "part_number": "PE", "verdict": verdict,
            "station": station, "operator": "ana", "clock": "real-time", "software_version": "0.1.0", "reason": "",
            "test_key": uuid.uuid4().hex, "record_sha256": uuid.uuid4().hex * 2, **more}


def _counts(url: str, query: object) -> dict[tuple, int]:
    """The counts by key (a key's rows summed: the day counts give a key once, its withdrawn rows again)."""
    engine = sa.create_engine(url)
    counted: dict[tuple, int] = {}
    with engine.connect() as conn:
        for row in conn.execute(query):  # type: ignore[call-overload]
            counted[tuple(row[:-1])] = counted.get(tuple(row[:-1]), 0) + int(row[-1])
    engine.dispose()
    return {key: n for key, n in counted.items() if n}


FILTERS = [
    Filters(),
    Filters(simulated=False),
    Filters(simulated=True),
    Filters(station="bench1"),
    Filters(shop="Nord", since="2026-11-02T09:30:00+00:00"),
    Filters(verdict="INVALID"),
    Filters(since="2026-11-02", until="2026-11-03"),
    # a local day's bounds (UTC+1): a partial day at either end
    Filters(since="2026-11-01T23:00:00+00:00", until="2026-11-03T22:59:59+00:00"),
    Filters(since="2026-11-02T09:30:00+00:00"),
    Filters(until="2026-11-02T09:30:00+00:00"),
    Filters(since="2026-11-02T09:30:00+00:00", until="2026-11-02T17:00:00+00:00"),
    Filters(since="2026-11-02T00:00:00+00:00", until="2026-11-02T23:59:59+00:00", station="bench2"),
]

#: Filters summed by month: whole months from the month counts, the days of a partial month from the day counts
#: (from the rows for a pump type), a local day's ends from the rows
MONTH_FILTERS = [
    Filters(),
    Filters(since="2026-09-15"),
    Filters(since="2026-10-01", until="2026-11-03"),
    Filters(since="2026-09-30T22:00:00+00:00", until="2026-11-02T12:00:00+00:00"),
    Filters(until="2026-10-31"),
    Filters(until="2026-10-31T23:59:59+00:00", since="2026-10-01T00:00:00+00:00"),
    Filters(since="2026-10-02", until="2026-10-30"),
    Filters(variant="p-edc-other"),
    Filters(variant="PO", since="2026-09-30", until="2026-12-01"),
    Filters(variant="p-edc-default", since="2026-09-30T23:00:00+00:00", until="2026-11-30T22:59:59+00:00"),
    Filters(station="bench1", since="2026-08-01"),
    Filters(shop="Nord", simulated=False),
    Filters(verdict="FAIL", until="2026-11-15"),
]


@pytest.fixture
def indexed(postgres_db: str) -> str:
    """Tests as stations index them: days, stations, verdicts, an INVALID's area, a retest, a simulated test, one
    indexed again with other content, one indexed twice alike, one withdrawn."""
    with HistoryStore(postgres_db) as store:
        for day in ("01", "02", "03", "04"):
            for hour, verdict in (("08", "PASS"), ("10", "FAIL"), ("18", "MARGINAL")):
                for station in ("bench1", "bench2"):
                    store.add_row(_row(station, f"2026-11-{day}T{hour}:00:00+00:00", verdict))
        store.add_row(_row("bench1", "2026-11-02T09:00:00+00:00", "INVALID", invalid_area="mounting"))
        store.add_row(_row("bench1", "2026-11-02T09:30:00+00:00", "PASS", retest_of="/records/x", decision="PASS"))
        store.add_row(_row("bench2", "2026-11-03T12:00:00+00:00", "PASS", simulated=True))
        twice = _row("bench2", "2026-11-02T11:00:00+00:00", "FAIL")
        assert store.add_row(dict(twice)) == "new" and store.add_row(dict(twice)) == "unchanged"
        assert store.add_row({**twice, "verdict": "PASS", "record_sha256": "c" * 64}) == "changed"
        gone = _row("bench1", "2026-11-03T15:00:00+00:00", "FAIL")
        store.add_row(gone)
        withdrawn = next(r for r in store.list() if r.record_dir == gone["record_dir"])
        store.withdraw_test(withdrawn.id, "mounted the wrong valve")
        store.map_login("login1", "bench1", None, "admin", shop="Nord")
        # months around it: a whole October, a day either side, another pump type, an October test withdrawn
        for started in ("2026-09-30T20:00:00+00:00", "2026-10-01T00:00:00+00:00", "2026-10-15T12:00:00+00:00",
                        "2026-10-31T23:59:59+00:00", "2026-12-01T07:00:00+00:00"):
            store.add_row(_row("bench1", started, "PASS"))
            store.add_row(_row("bench2", started, "FAIL", variant="p-edc-other", part_number="PO"))
        gone = _row("bench2", "2026-10-20T15:00:00+00:00", "FAIL", variant="p-edc-other", part_number="PO")
        store.add_row(gone)
        store.withdraw_test(next(r for r in store.list() if r.record_dir == gone["record_dir"]).id, "wrong pump")
    return postgres_db


def _by_month(counts: dict[tuple, int]) -> dict[tuple, int]:
    months: dict[tuple, int] = {}
    for (day, *rest), n in counts.items():
        months[(day[:7], *rest)] = months.get((day[:7], *rest), 0) + n
    return {key: n for key, n in months.items() if n}


@pytest.mark.parametrize("filters", FILTERS, ids=[str(n) for n in range(len(FILTERS))])
def test_the_day_counts_give_what_the_rows_give(indexed: str, filters: Filters) -> None:
    from_rows = _counts(indexed, counted_from_rows(filters))
    assert from_rows, "the filter selects tests"
    assert _counts(indexed, counted_from_counts(filters)) == from_rows


@pytest.mark.parametrize("filters", MONTH_FILTERS, ids=[str(n) for n in range(len(MONTH_FILTERS))])
def test_the_month_counts_give_what_the_rows_give(indexed: str, filters: Filters) -> None:
    from_rows = _by_month(_counts(indexed, counted_from_rows(filters)))
    assert from_rows, "the filter selects tests"
    assert _by_month(_counts(indexed, counted_from_counts(filters, "month"))) == from_rows


def test_the_chain_summary_is_the_same_whichever_source(indexed: str, monkeypatch: pytest.MonkeyPatch) -> None:
    import edc_bench.history.summary as summary

    now = dt.datetime(2026, 11, 5, tzinfo=dt.UTC)
    with HistoryStore(indexed) as store:
        kept = [chain_summary(store, f, now=now) for f in FILTERS + MONTH_FILTERS]
        monkeypatch.setattr(summary, "counts_answer", lambda _filters, _period: False)  # the rows, every time
        counted = [chain_summary(store, f, now=now) for f in FILTERS + MONTH_FILTERS]
    assert kept == counted
    assert kept[0].tests == 38 and kept[0].retests == 1 and dict(kept[0].invalid_areas) == {"mounting": 1}
    assert kept[0].period == "month" and {d.day for d in kept[0].per_day} == {"2026-09", "2026-10", "2026-11",
                                                                             "2026-12"}


def test_counts_changed_outside_edc_bench_are_named_by_verify(indexed: str) -> None:
    engine = sa.create_engine(indexed)
    with engine.connect() as conn:
        assert mismatches(conn) == []
    engine.dispose()
    with psycopg.connect(indexed.replace("postgresql+psycopg://", "postgresql://")) as conn:  # the owner's rights
        conn.execute("UPDATE test_day_counts SET tests = tests + 5 WHERE station = 'bench2' AND day = '2026-11-04' "
                     "AND verdict = 'FAIL'")
        conn.execute("UPDATE test_month_counts SET tests = 0 WHERE station = 'bench2' AND month = '2026-10'")
    found = edc_bench("history", "--verify", "--db", indexed)
    assert found.returncode == 16
    assert "the day count of bench2 on 2026-11-04 (FAIL) is 6, the rows count 1" in found.stdout, found.stdout
    # October's FAIL of the other pump type: three tests and the withdrawn one (counted, subtracted where read)
    assert "the month count of bench2 in 2026-10 (p-edc-other PO, FAIL) is 0, the rows count 4" in found.stdout


def test_a_station_may_not_write_the_counts(postgres_db: str) -> None:
    from edc_bench.history.roles import setup_roles

    engine = sa.create_engine(postgres_db)
    with engine.begin() as conn:
        setup_roles(conn)
        conn.exec_driver_sql("DO $$ BEGIN IF NOT EXISTS (SELECT FROM pg_roles WHERE rolname = 'bench9') THEN "
                             "CREATE ROLE bench9 LOGIN; END IF; END $$")
        conn.exec_driver_sql("GRANT edc_station TO bench9")
    engine.dispose()
    with HistoryStore(postgres_db) as owner:
        owner.map_login("bench9", "Werkstatt 9", None, "admin")
    station = postgres_db.replace("://postgres@", "://bench9@")
    with HistoryStore(station) as store:
        assert store.add_row(_row("ignored", "2026-11-02T08:00:00+00:00", "PASS")) == "new"  # counted by the trigger
    with psycopg.connect(station.replace("postgresql+psycopg://", "postgresql://")) as conn:
        for sql in ("UPDATE test_day_counts SET tests = 0", "UPDATE test_month_counts SET tests = 0",
                    "INSERT INTO test_day_counts VALUES ('2026-11-02', 'Werkstatt 9', 'PASS', true, '', false, 9)",
                    "DELETE FROM test_month_counts"):
            with pytest.raises(psycopg.errors.InsufficientPrivilege):
                conn.execute(sql)
            conn.rollback()
    assert _counts(postgres_db, counted_from_counts(Filters())) == _counts(postgres_db,
                                                                                counted_from_rows(Filters()))


def test_the_benchmarks_bulk_chain_holds_its_counts(new_postgres_database: object) -> None:
    url = new_postgres_database()  # type: ignore[operator]
    fill_bulk_chain(url, 3000, stations=5, now=dt.datetime(2026, 11, 27, tzinfo=dt.UTC))
    engine = sa.create_engine(url)
    with engine.connect() as conn:
        assert mismatches(conn) == []
    engine.dispose()
    year = Filters(since="2025-11-27", simulated=False)
    assert _counts(url, counted_from_counts(year)) == _counts(url, counted_from_rows(year))
    for filters in (year, Filters(since="2025-11-27T23:00:00+00:00", variant="p-edc-default")):
        assert _by_month(_counts(url, counted_from_counts(filters, "month"))) == _by_month(
            _counts(url, counted_from_rows(filters)))
