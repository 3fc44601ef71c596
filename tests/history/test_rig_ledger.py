"""The rig self-check's ledger in the history: revision 0005 on an older history keeps its rows, the new tables
refuse changes, a station adds checks and only an engineer registers a reference valve."""

from __future__ import annotations

import sqlite3
from collections.abc import Callable
from pathlib import Path

import pytest
import sqlalchemy as sa

from edc_bench.history import migrate
from edc_bench.history.store import HistoryStore
from edc_bench.selfcheck import Registration, registration_row
from edc_bench.selfcheck.compare import ReferenceValues

VALUES = ReferenceValues(lvdt_zero_mm=0.005, current_zero_a=0.002, coil_r20_ohm=0.70, a0_v_per_mm=0.216,
                         af_v=0.0716, a1_v_s_per_mm=0.0039)


def _reference_row(station: str = "bench1", valve_id: str = "REF-1") -> dict:
    return registration_row(VALUES, station=station, valve_id=valve_id, variant="p-edc-default", by="ana",
                            simulated=False, details={"rig": "bus"})


def _check_row(reference_id: int, verdict: str = "GO") -> dict:
    return {"station": "bench1", "reference_id": reference_id, "verdict": verdict, "causes": "", "words": "x",
            **VALUES.figures(), "lvdt_at_floor": False, "coil_temp_c": 20.0, "simulated": False, "details": "{}",
            "software_version": "0.1.0", "checked_by": "ben"}


def _history_at(url: str, revision: str) -> None:
    """A history as an edc-bench of ``revision`` left it."""
    from alembic import command

    engine = sa.create_engine(url)
    with engine.begin() as conn:
        command.upgrade(migrate._config(conn), revision)
    engine.dispose()


def test_revision_0005_on_an_older_history_keeps_its_rows_and_refuses_changes_to_the_ledger(tmp_path: Path) -> None:
    path = tmp_path / "h.sqlite"
    url = f"sqlite:///{path}"
    _history_at(url, "0004")
    with sqlite3.connect(path) as conn:
        conn.execute("INSERT INTO tests (record_dir, started_at, valve_id, pump_serial, variant, part_number, verdict, "
                     "station, operator, clock, software_version, reason) VALUES ('/r/a', '2026-05-01T08:00:00+00:00', "
                     "'V1', 'S', 'p-edc-default', 'PE', 'PASS', 'bench1', 'ana', 'real-time', '0.1.0', '')")
        conn.execute("INSERT INTO teardowns (valve_id, finding, note, labelled_by, labelled_at, recorded_at) VALUES "
                     "('V1', 'worn', '', 'ana', '2026-05-02', '2026-05-02')")
    with HistoryStore(url) as store:  # a station's SQLite file is upgraded when opened
        with store.engine.connect() as conn:
            assert migrate.current(conn) == migrate.head()
        assert [r.valve_id for r in store.list()] == ["V1"] and len(store.teardowns()) == 1
        assert store.reference("bench1") is None and store.rig_checks() == []
        first = store.add_reference(_reference_row())
        second = store.add_reference(_reference_row(valve_id="REF-2"))  # a registration again: a new row
        registration = Registration.of(store.reference("bench1"))
        assert registration is not None and registration.id == second.id != first.id
        assert registration.values == VALUES and not registration.simulated
        store.add_rig_check(_check_row(second.id))
        assert [c.verdict for c in store.rig_checks("bench1", second.id)] == ["GO"]
        assert store.tests_since("bench1", "2026-04-30") == 1 and store.tests_since("bench1", "2026-05-02") == 0
    with sqlite3.connect(path) as conn:
        for sql in ("UPDATE reference_valves SET af_v = 1", "DELETE FROM reference_valves",
                    "UPDATE rig_checks SET verdict = 'GO'", "DELETE FROM rig_checks"):
            with pytest.raises(sqlite3.IntegrityError, match="append-only"):
                conn.execute(sql)


def test_a_check_is_due_after_the_tests_a_variant_allows_counted_from_the_last_check(tmp_path: Path) -> None:
    import datetime as dt

    from edc_bench.selfcheck import SelfCheckPolicy, check_due

    with HistoryStore(f"sqlite:///{tmp_path / 'h.sqlite'}") as store:
        registration = Registration.of(store.add_reference(_reference_row()))
        assert registration is not None
        now = dt.datetime.fromisoformat(registration.registered_at) + dt.timedelta(hours=1)
        policy = SelfCheckPolicy(every_tests=2, every_hours=8)
        assert check_due(store, registration, policy, now) is None  # the registration counts as a check
        for n in range(2):
            row = {name: "" for name in ("pump_serial", "variant", "part_number", "operator", "clock",
                                          "software_version", "reason")}
            store.add_row({**row, "record_dir": f"/r/{n}", "started_at": "2999-01-01T00:00:00+00:00",
                           "valve_id": f"V{n}", "verdict": "PASS", "station": "bench1"})
        assert check_due(store, registration, policy, now).startswith("2 tests since the last rig self-check")
        assert check_due(store, registration, policy, now + dt.timedelta(hours=8)) is not None
        store.add_rig_check(_check_row(registration.id, "NO-GO"))
        assert "was NO-GO" in check_due(store, registration, SelfCheckPolicy(), now)


def test_a_station_adds_checks_and_only_an_engineer_registers(new_postgres_database: Callable[..., str]) -> None:
    from edc_bench.errors import ConfigError
    from edc_bench.history.roles import setup_roles

    url = new_postgres_database()
    owner = sa.create_engine(url)
    with owner.begin() as conn:
        setup_roles(conn)
        for login, role in (("bench7", "edc_station"), ("ines7", "edc_engineer")):
            conn.exec_driver_sql(f"DO $$ BEGIN IF NOT EXISTS (SELECT FROM pg_roles WHERE rolname = '{login}') THEN "
                                 f"CREATE ROLE {login} LOGIN; END IF; END $$")
            conn.exec_driver_sql(f"GRANT {role} TO {login}")
    with HistoryStore(url) as chain_owner:  # the owner says which station the login is
        chain_owner.map_login("bench7", "bench1", None, "admin")
    with HistoryStore(url.replace("://postgres@", "://bench7@")) as station:
        with pytest.raises(ConfigError, match="'bench7' may not register a reference valve: ask the engineer's login"):
            station.add_reference(_reference_row())
    with HistoryStore(url.replace("://postgres@", "://ines7@")) as engineer:
        reference = engineer.add_reference(_reference_row())
        assert reference.db_login == "ines7"
    with HistoryStore(url.replace("://postgres@", "://bench7@")) as station:
        check = station.add_rig_check(_check_row(reference.id, "NO-GO"))
        assert check.db_login == "bench7" and station.rig_checks("bench1")[0].verdict == "NO-GO"
    with owner.connect() as conn:
        for sql in ("UPDATE rig_checks SET verdict = 'GO'", "DELETE FROM reference_valves", "TRUNCATE rig_checks"):
            with pytest.raises(sa.exc.DBAPIError, match="append-only"):
                conn.exec_driver_sql(sql)
            conn.rollback()
    owner.dispose()
