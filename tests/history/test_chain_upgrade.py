"""Revision 0006 on a history an earlier edc-bench kept: every row kept, the old rows anchored (not rehashed), a
folder indexed twice before shown as a test and its change, and an old row changed afterwards found; the later
revisions' counts (0008, 0009) filled in from the old rows."""

from __future__ import annotations

from pathlib import Path

import pytest
import sqlalchemy as sa

from edc_bench.history import day_counts, migrate
from edc_bench.history.chain import legacy_test_key
from edc_bench.history.store import HistoryStore

_OLD_TEST = ("INSERT INTO tests (record_dir, started_at, valve_id, pump_serial, variant, part_number, verdict, station, "
             "operator, clock, software_version, reason, record_sha256) VALUES (:d, :t, :v, 'S', 'p-edc-default', "
             "'PE', :verdict, 'bench1', 'ana', 'real-time', '0.1.0', '', :sha)")


def _history_at(url: str, revision: str) -> None:
    from alembic import command

    engine = sa.create_engine(url)
    with engine.begin() as conn:
        command.upgrade(migrate._config(conn), revision)
    engine.dispose()


def _old_rows(url: str) -> None:
    """What revision 0005's edc-bench wrote: three tests (one folder indexed twice: FAIL, then PASS) and a finding."""
    engine = sa.create_engine(url)
    with engine.begin() as conn:
        for folder, started, valve, verdict, sha in (("/r/a", "2026-05-01T08:00:00+00:00", "V1", "FAIL", "a" * 64),
                                                     ("/r/b", "2026-05-02T08:00:00+00:00", "V2", "PASS", "b" * 64),
                                                     ("/r/a", "2026-05-01T08:00:00+00:00", "V1", "PASS", "c" * 64)):
            conn.execute(sa.text(_OLD_TEST), {"d": folder, "t": started, "v": valve, "verdict": verdict, "sha": sha})
        conn.exec_driver_sql("INSERT INTO teardowns (valve_id, finding, note, labelled_by, labelled_at, recorded_at) "
                             "VALUES ('V1', 'worn', '', 'ines', '2026-05-03', '2026-05-03')")
    engine.dispose()


@pytest.fixture(params=["sqlite", pytest.param("postgresql", marks=pytest.mark.slow)])
def old_history(request: pytest.FixtureRequest, tmp_path: Path) -> str:
    if request.param == "sqlite":
        url = f"sqlite:///{tmp_path / 'h.sqlite'}"
    else:
        url = request.getfixturevalue("new_postgres_database")(upgrade=False)
    _history_at(url, "0005")
    _old_rows(url)
    return url


def test_the_chain_revision_keeps_every_row_and_anchors_the_old_ones(old_history: str) -> None:
    migrate.upgrade(sa.create_engine(old_history))
    with HistoryStore(old_history) as store:
        assert store.chain_breaks() == []
        listed = store.list()
        # the folder indexed twice before: its first indexing stands, the second is its change
        assert [(r.valve_id, r.verdict, r.changes) for r in listed] == [("V1", "FAIL", 1), ("V2", "PASS", 0)]
        assert listed[0].test_key == legacy_test_key("2026-05-01T08:00:00+00:00", "V1", "S", "bench1")
        assert len(store.teardowns()) == 1
        # a new row follows the anchor of its chain
        assert store.add_row({"record_dir": "/r/c", "started_at": "2026-06-01T08:00:00+00:00", "valve_id": "V3",
                              "pump_serial": "S", "variant": "p-edc-default", "part_number": "PE", "verdict": "PASS",
                              "station": "bench1", "operator": "ana", "clock": "real-time",
                              "software_version": "0.1.0", "reason": "", "record_sha256": "d" * 64}) == "new"
        # old rows say nothing of their first indexing (revision 0008): readers ask the rows before them, as
        # above; the rows added since say it, and one indexed again is a change beside the old ones
        row = {**store.list()[0].columns(), "record_sha256": "e" * 64, "verdict": "INVALID"}
        assert store.add_row(row) == "changed"
        assert [(r.valve_id, r.verdict, r.changes) for r in store.list()] == [
            ("V1", "FAIL", 2), ("V2", "PASS", 0), ("V3", "PASS", 0)]
        assert store.first_indexing_mismatches() == [] and store.chain_breaks() == []
    with sa.create_engine(old_history).connect() as conn:
        flags = conn.exec_driver_sql("SELECT valve_id, first_indexing FROM tests ORDER BY id").all()
        # PostgreSQL's day and month counts (revisions 0008, 0009): the old rows filled in, the new ones counted
        assert day_counts.mismatches(conn) == []
        if conn.dialect.name == "postgresql":
            assert conn.exec_driver_sql("SELECT month, sum(tests) FROM test_month_counts GROUP BY month "
                                        "ORDER BY month").all() == [
                ("2026-05", 2), ("2026-06", 1)]
    assert [tuple(f) for f in flags] == [("V1", None), ("V2", None), ("V1", None), ("V3", True), ("V1", False)]
    with HistoryStore(old_history) as store:
        assert store.chain_breaks() == []
    engine = sa.create_engine(old_history)
    with engine.begin() as conn:  # an old row changed afterwards, the triggers held off (the owner's rights)
        if engine.dialect.name == "postgresql":
            conn.exec_driver_sql("ALTER TABLE tests DISABLE TRIGGER tests_append_only")
            conn.exec_driver_sql("UPDATE tests SET verdict = 'PASS' WHERE id = 1")
            conn.exec_driver_sql("ALTER TABLE tests ENABLE TRIGGER tests_append_only")
        else:
            conn.exec_driver_sql("DROP TRIGGER tests_no_update")
            conn.exec_driver_sql("UPDATE tests SET verdict = 'PASS' WHERE id = 1")
    engine.dispose()
    with HistoryStore(old_history, warn=lambda _: None) as store:
        lines = [b.line() for b in store.chain_breaks()]
    assert lines == ["table tests (chain bench1): the 3 row(s) written before the chain began are not as anchored "
                     "(3 there now; edited or deleted)"], lines


def test_an_old_history_of_a_station_is_upgraded_when_opened(tmp_path: Path) -> None:
    url = f"sqlite:///{tmp_path / 'h.sqlite'}"
    _history_at(url, "0005")
    _old_rows(url)
    with HistoryStore(url) as store:  # a station's own file: brought to this revision as it is opened
        with store.engine.connect() as conn:
            assert migrate.current(conn) == migrate.head()
        assert store.problems == [] and len(store.list()) == 2
