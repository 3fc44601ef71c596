"""Eight stations adding tests to one PostgreSQL history while an engineer labels, trains from it and exports:
nothing lost, no deadlock, every row once (slow: a minute of processes)."""

from __future__ import annotations

import io
import multiprocessing
import time
from typing import Any

import pytest
import sqlalchemy as sa

from edc_bench.history.roles import ENGINEER, STATION, setup_roles
from edc_bench.history.schema import COLUMNS
from edc_bench.history.store import HistoryStore, write_csv

STATIONS = 8
TESTS_PER_STATION = 60


def _row(station: int, n: int) -> dict[str, Any]:
    row = {name: None for name in COLUMNS if name not in ("id", "indexed_at", "indexed_by")}
    row.update(record_dir=f"/records/st{station}/{n:04d}", started_at=f"2026-11-26T08:{n // 60:02d}:{n % 60:02d}",
               valve_id=f"V-{station}-{n}", pump_serial=f"P-{station}", variant="p-edc-default",
               part_number="PE-EDC-0001", verdict="PASS", af_rel=1.0 + n / 100, a1_rel=1.0 + station / 100,
               station=f"bench{station}", operator="ana", clock="simulated", software_version="0.1.0", reason="")
    return row


def _station(url: str, station: int, start: Any, done: Any) -> None:
    start.wait()
    with HistoryStore(url) as store:
        for n in range(TESTS_PER_STATION):
            store.add_row(_row(station, n), indexed_by=f"bench{station}")
    done.put(station)


def _engineer(url: str, start: Any, results: Any) -> None:
    """Labels valves as they are tested (worn above af 1.3), trains a candidate from the labels once there are enough
    (as 'train --from-history' does, the labels alone), and exports, until every station's tests are in."""
    from edc_bench.history.labels import labelled_tests
    from edc_bench.learning.shop_training import MIN_LABELS, train_from_labels
    from edc_bench.verdict.classifier import ValveClassifier

    start.wait()
    labels = exports = trainings = 0
    opened: set[str] = set()
    with HistoryStore(url) as store:
        deadline = time.monotonic() + 240
        while time.monotonic() < deadline:
            for row in [r for r in store.list() if r.valve_id not in opened][:3]:  # valves tested, not yet opened
                finding = "worn" if row.af_rel > 1.3 else "reusable"
                store.add_teardown(row.valve_id, finding, labelled_by="ines", labelled_at="2026-11-26T23:00")
                opened.add(row.valve_id)
                labels += 1
            labelled = labelled_tests(store)
            if trainings == 0 and len(labelled.labels) >= MIN_LABELS and 5 <= labelled.labels.sum() \
                    <= len(labelled.labels) - 5:
                train_from_labels(labelled, None, ValveClassifier(), prior_weight=0, seed=1)
                trainings += 1
            exports += write_csv(store.list(), io.StringIO()) >= 0
            if len(store.list()) == STATIONS * TESTS_PER_STATION and trainings:
                break
    results.put({"labels": labels, "exports": exports, "trainings": trainings})


@pytest.mark.slow
def test_eight_stations_and_an_engineer_at_once_lose_nothing(postgres_db: str) -> None:
    engine = sa.create_engine(postgres_db)
    with engine.begin() as conn:
        setup_roles(conn)
        for login, role in [*((f"bench{n}", STATION) for n in range(STATIONS)), ("ines", ENGINEER)]:
            # the server's roles outlive a test's database: another test may have made this login already
            conn.exec_driver_sql(f"DO $$ BEGIN IF NOT EXISTS (SELECT FROM pg_roles WHERE rolname = '{login}') THEN "
                                 f"CREATE ROLE {login} LOGIN; END IF; END $$")
            conn.exec_driver_sql(f"GRANT {role} TO {login}")
    engine.dispose()
    with HistoryStore(postgres_db) as owner:  # each station's login is that station (docs/shop-network.md)
        for n in range(STATIONS):
            owner.map_login(f"bench{n}", f"bench{n}", None, "admin")
    as_login = lambda login: postgres_db.replace("://postgres@", f"://{login}@")  # noqa: E731
    ctx = multiprocessing.get_context("spawn")
    start, done, results = ctx.Barrier(STATIONS + 1), ctx.Queue(), ctx.Queue()
    procs = [ctx.Process(target=_station, args=(as_login(f"bench{n}"), n, start, done)) for n in range(STATIONS)]
    procs.append(ctx.Process(target=_engineer, args=(as_login("ines"), start, results)))
    began = time.monotonic()
    for proc in procs:
        proc.start()
    for proc in procs:
        proc.join(300)
    elapsed = time.monotonic() - began
    assert [proc.exitcode for proc in procs] == [0] * (STATIONS + 1), "a process failed or hung (deadlock?)"
    engineer = results.get(timeout=5)
    with HistoryStore(postgres_db) as store:
        rows = store.list()
        teardowns = store.teardowns()
    per_station = {n: sum(r.station == f"bench{n}" for r in rows) for n in range(STATIONS)}
    print(f"\n{STATIONS} stations x {TESTS_PER_STATION} tests in {elapsed:.1f} s: {len(rows)} rows, "
          f"per station {sorted(per_station.values())}; engineer: {engineer['labels']} findings, "
          f"{engineer['trainings']} training(s) from the history, {engineer['exports']} exports; {len(teardowns)} findings "
          "stored")
    assert len(rows) == STATIONS * TESTS_PER_STATION  # nothing lost
    assert len({r.record_dir for r in rows}) == len(rows)  # every row once
    assert all(count == TESTS_PER_STATION for count in per_station.values())
    assert len(teardowns) == engineer["labels"] > 0 and engineer["exports"] > 0 and engineer["trainings"] == 1
    assert store_breaks(postgres_db) == []  # eight writers at once, and every station's chain holds


def store_breaks(url: str) -> list[str]:
    with HistoryStore(url) as store:
        return [b.line() for b in store.chain_breaks()]
