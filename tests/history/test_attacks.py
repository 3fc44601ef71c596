"""A chain's history tried as an attacker at one of its stations would (issue #51): every right a station's login
has, used against the rows of others, on a real PostgreSQL server, and a station's own SQLite file changed with
the sqlite3 program. Each attack is refused by the database, or named by ``history --verify``: each test says
which."""

from __future__ import annotations

import json
import os
import shutil
import sqlite3
import subprocess
import sys
import uuid
from collections.abc import Callable
from pathlib import Path

import psycopg
import pytest
import sqlalchemy as sa
from helpers import edc_bench

from edc_bench.bench import run_simulated_test
from edc_bench.config import load_variant
from edc_bench.history.roles import setup_roles
from edc_bench.history.store import HistoryStore
from edc_bench.records.integrity import manifest
from edc_bench.records.reader import load_record
from edc_bench.records.record import write_record


@pytest.fixture(scope="module")
def fail_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """One simulated test's record folder: a faulty valve, FAIL."""
    folder = write_record(run_simulated_test(load_variant(), "faulty", 3), tmp_path_factory.mktemp("records"),
                          figure=False)
    assert load_record(folder).verdict == "FAIL"
    return folder


def _login(url: str, login: str) -> str:
    return url.replace("://postgres@", f"://{login}@")


def _dsn(url: str) -> str:
    return url.replace("postgresql+psycopg://", "postgresql://")


@pytest.fixture
def chain(postgres_db: str) -> dict[str, str]:
    """A chain as docs/shop-network.md sets it up: roles, two stations' logins mapped to their stations, an
    engineer. Returns the URLs by login ('owner': the superuser that made it)."""
    engine = sa.create_engine(postgres_db)
    with engine.begin() as conn:
        setup_roles(conn)
        for login, role in (("bench3", "edc_station"), ("bench4", "edc_station"), ("ines", "edc_engineer"),
                            ("nomap", "edc_station")):
            conn.exec_driver_sql(f"DO $$ BEGIN IF NOT EXISTS (SELECT FROM pg_roles WHERE rolname = '{login}') THEN "
                                 f"CREATE ROLE {login} LOGIN; END IF; END $$")
            conn.exec_driver_sql(f"GRANT {role} TO {login}")
    engine.dispose()
    with HistoryStore(postgres_db) as owner:
        owner.map_login("bench3", "Werkstatt Nord 3", None, "admin")
        owner.map_login("bench4", "Werkstatt Süd 4", None, "admin")
        owner.map_login("ines", None, "Ines Braun", "admin")
    return {"owner": postgres_db, **{login: _login(postgres_db, login) for login in ("bench3", "bench4", "ines",
                                                                                      "nomap")}}


def _row(valve: str, verdict: str = "FAIL", key: str | None = None, sha: str = "a" * 64) -> dict:
    return {"record_dir": f"/records/{valve}", "started_at": "2026-11-20T08:00:00+00:00", "valve_id": valve,
            "pump_serial": "P-1", "variant": "p-edc-default", "part_number": "PE", "verdict": verdict,
            "station": "ignored", "operator": "ana", "clock": "real-time", "software_version": "0.1.0",
            "reason": "", "test_key": key or uuid.uuid4().hex, "record_sha256": sha}


_INSERT = ("INSERT INTO tests (id, record_dir, started_at, valve_id, pump_serial, variant, part_number, verdict, "
           "station, operator, clock, software_version, reason, test_key, record_sha256, record_manifest, indexed_at, "
           "db_login) VALUES (%(id)s, %(record_dir)s, %(started_at)s, %(valve_id)s, %(pump_serial)s, %(variant)s, "
           "%(part_number)s, %(verdict)s, %(station)s, %(operator)s, %(clock)s, %(software_version)s, %(reason)s, "
           "%(test_key)s, %(record_sha256)s, %(record_manifest)s, %(indexed_at)s, %(db_login)s) RETURNING *")


def _raw_insert(url: str, row: dict) -> dict:
    """INSERT as the attacker types it in psql: every column its own choice."""
    values = {"id": None, "record_manifest": None, "indexed_at": None, "db_login": None, **row}
    with psycopg.connect(_dsn(url), row_factory=psycopg.rows.dict_row) as conn:
        return conn.execute(_INSERT, values).fetchone()


def _verify(url: str, *args: str) -> subprocess.CompletedProcess:
    return edc_bench("history", "--verify", *args, "--db", url)


# --- PostgreSQL: what a station inserts cannot claim what the server knows better --------------------------------


def test_a_forged_station_login_time_and_id_are_the_servers_own(chain: dict[str, str]) -> None:
    stored = _raw_insert(chain["bench3"], {**_row("V-1"), "id": 999_999, "station": "Werkstatt Süd 4",
                                           "db_login": "bench4", "indexed_at": "2020-01-01T00:00:00+00:00"})
    assert stored["id"] < 1000, "the id is the sequence's"
    assert stored["station"] == "Werkstatt Nord 3" and stored["db_login"] == "bench3"
    assert stored["indexed_at"] > "2026-"  # the server's clock, not the row's claim
    listed = HistoryStore(chain["owner"]).list()
    assert [(r.valve_id, r.station) for r in listed] == [("V-1", "Werkstatt Nord 3")]
    assert _verify(chain["owner"], "--station", "Werkstatt Nord 3").stdout.count("missing:") == 1  # a phantom folder


def test_a_row_without_a_test_key_cannot_hide_the_others(chain: dict[str, str]) -> None:
    with HistoryStore(chain["bench4"]) as other:
        other.add_row(_row("V-kept"))
    stored = _raw_insert(chain["bench3"], {**_row("V-nokey"), "test_key": None})
    assert stored["test_key"] == "folder:/records/V-nokey"
    with HistoryStore(chain["ines"]) as engineer:
        engineer.withdraw_test(stored["id"], "never tested")
    assert [r.valve_id for r in HistoryStore(chain["owner"]).list()] == ["V-kept"]


def test_a_block_of_ids_ahead_of_the_sequence_blocks_no_station(chain: dict[str, str]) -> None:
    for n in range(5):
        _raw_insert(chain["bench3"], {**_row(f"V-block-{n}"), "id": 2 + n})  # the ids the next rows would take
    with HistoryStore(chain["bench4"]) as other:
        assert other.add_row(_row("V-after")) == "new"  # the next station's indexing is not refused
    ids = [r.id for r in HistoryStore(chain["owner"]).list()]
    assert len(set(ids)) == 6


def test_a_copy_of_another_stations_fail_as_pass_is_refused(chain: dict[str, str]) -> None:
    with HistoryStore(chain["bench4"]) as other:
        assert other.add_row(_row("V-2", "FAIL", key="K-2", sha="b" * 64)) == "new"
    original = HistoryStore(chain["owner"]).list()[0]
    # the same test and hash (copied from the readable row): the unique key refuses it
    with pytest.raises(psycopg.errors.UniqueViolation):
        _raw_insert(chain["bench3"], {**_row("V-2", "PASS", key="K-2", sha="b" * 64),
                                      "record_manifest": original.record_sha256})
    # the same test with other content: refused, it is another station's test
    with pytest.raises(psycopg.errors.InsufficientPrivilege, match="first indexed by another station"):
        _raw_insert(chain["bench3"], _row("V-2", "PASS", key="K-2", sha="c" * 64))
    listed = HistoryStore(chain["owner"]).list()
    assert [(r.verdict, r.station, r.changes) for r in listed] == [("FAIL", "Werkstatt Süd 4", 0)]


def test_a_backdated_pass_for_a_folder_that_never_existed_is_the_attackers_and_found_missing(
        chain: dict[str, str]) -> None:
    _raw_insert(chain["bench3"], {**_row("V-ghost", "PASS"), "started_at": "2025-01-01T08:00:00+00:00",
                                  "record_dir": "/records/never-there"})
    found = _verify(chain["owner"], "--station", "Werkstatt Nord 3")
    assert found.returncode == 16 and "missing: test" in found.stdout and "never-there" in found.stdout
    assert "Werkstatt Nord 3" in HistoryStore(chain["owner"]).list()[0].station  # attributed to its writer
    # the other station's own check is not disturbed by it
    assert _verify(chain["owner"], "--station", "Werkstatt Süd 4").returncode == 0


def test_a_login_mapped_to_no_station_may_add_no_tests(chain: dict[str, str]) -> None:
    with pytest.raises(psycopg.errors.InsufficientPrivilege, match="mapped to no station"):
        _raw_insert(chain["nomap"], _row("V-3"))
    refused = edc_bench("history", "--map-login", "bench9", "--station", "x", "--db", chain["bench3"])
    assert refused.returncode == 2 and "may not say which station a database login is" in refused.stderr
    assert len(refused.stderr.strip().splitlines()) == 1


def test_a_forged_rig_self_check_for_another_station_is_refused(chain: dict[str, str]) -> None:
    with HistoryStore(chain["ines"]) as engineer:
        reference = engineer.add_reference({
            "station": "Werkstatt Süd 4", "valve_id": "REF-1", "variant": "p-edc-default", "simulated": True,
            "software_version": "0.1.0", "registered_by": "someone else"})
    assert reference.registered_by == "Ines Braun" and reference.db_login == "ines"  # the login's person
    with psycopg.connect(_dsn(chain["bench3"])) as conn:
        with pytest.raises(psycopg.errors.InsufficientPrivilege, match="is not station Werkstatt Nord 3's"):
            conn.execute("INSERT INTO rig_checks (station, reference_id, verdict, causes, words, simulated, "
                         "software_version, checked_by, checked_at) VALUES ('Werkstatt Süd 4', %s, 'NO-GO', 'af', "
                         "'drifted', true, '0.1.0', 'x', '2020-01-01')", (reference.id,))
    assert HistoryStore(chain["owner"]).rig_checks() == []


def test_an_engineer_files_findings_and_withdrawals_only_as_itself(chain: dict[str, str]) -> None:
    with HistoryStore(chain["bench3"]) as station:
        station.add_row(_row("V-5"))
    with psycopg.connect(_dsn(chain["ines"]), row_factory=psycopg.rows.dict_row) as conn:
        finding = conn.execute("INSERT INTO teardowns (valve_id, finding, note, labelled_by, labelled_at, recorded_at, "
                               "db_login) VALUES ('V-5', 'worn', '', 'ines', '2026-11-20', '2020-01-01', 'boss') "
                               "RETURNING *").fetchone()
        withdrawal = conn.execute("INSERT INTO amendments (target, target_id, action, reason, amended_by, "
                                  "amended_at, db_login) VALUES ('tests', 1, 'withdraw', 'x', 'the boss', "
                                  "'2020-01-01', 'boss') RETURNING *").fetchone()
        with pytest.raises(psycopg.errors.InsufficientPrivilege, match="names no stored row"):
            conn.execute("INSERT INTO amendments (target, target_id, action, reason, amended_by, amended_at) VALUES "
                         "('tests', 424242, 'withdraw', 'x', 'y', 'z')")
    assert finding["db_login"] == "ines" and finding["recorded_at"] > "2026-"
    assert (withdrawal["db_login"], withdrawal["amended_by"]) == ("ines", "Ines Braun")
    # a station's login may write neither, nor a login's mapping
    with psycopg.connect(_dsn(chain["bench3"])) as conn:
        for sql in ("INSERT INTO amendments (target, target_id, action, reason, amended_by, amended_at) VALUES "
                    "('tests', 1, 'withdraw', 'x', 'y', 'z')",
                    "INSERT INTO edc_logins (login, station, mapped_by, mapped_at) VALUES ('bench3', 'Werkstatt Süd "
                    "4', 'x', 'y')",
                    "ALTER TABLE tests DISABLE TRIGGER ALL", "SET session_replication_role = replica"):
            with pytest.raises(psycopg.errors.InsufficientPrivilege):
                conn.execute(sql)
            conn.rollback()


def test_a_row_changed_with_the_triggers_off_breaks_the_chain_where_it_was_done(chain: dict[str, str]) -> None:
    """What the owner's (or a superuser's) rights could still do to one row is named by --verify."""
    with HistoryStore(chain["bench3"]) as station:
        for n in range(3):
            station.add_row(_row(f"V-6{n}"))
    assert _verify(chain["owner"], "--station", "Werkstatt Nord 3").stdout.count("chain:") == 0
    with psycopg.connect(_dsn(chain["owner"])) as conn:
        conn.execute("ALTER TABLE tests DISABLE TRIGGER tests_append_only")
        conn.execute("UPDATE tests SET verdict = 'PASS' WHERE valve_id = 'V-61'")
        conn.execute("DELETE FROM tests WHERE valve_id = 'V-60'")
        conn.execute("ALTER TABLE tests ENABLE TRIGGER tests_append_only")
    found = _verify(chain["owner"], "--station", "Werkstatt Nord 3")
    assert found.returncode == 16
    chain_lines = [line for line in found.stdout.splitlines() if line.startswith("chain:")]
    assert any("row 2 of tests" in line and "was edited" in line for line in chain_lines), found.stdout
    assert any("row 2 of tests" in line and "deleted or put in" in line for line in chain_lines), found.stdout


def _insert_claiming_first(url: str, row: dict) -> dict:
    """An INSERT that says the row is its test's first indexing (revision 0008's column), as typed in psql."""
    columns = [*row, "first_indexing"]
    with psycopg.connect(_dsn(url), row_factory=psycopg.rows.dict_row) as conn:
        return conn.execute(f"INSERT INTO tests ({', '.join(columns)}) VALUES "
                            f"({', '.join(f'%({c})s' for c in columns)}) RETURNING *",
                            {**row, "first_indexing": True}).fetchone()


def test_a_stations_claim_that_its_row_is_a_tests_first_indexing_is_the_servers_to_make(
        chain: dict[str, str]) -> None:
    """Readers take a row's first_indexing as which row stands: a station re-indexing its own FAIL as PASS and
    saying the PASS is the first would have two standing rows, the PASS counted."""
    with HistoryStore(chain["bench3"]) as station:
        assert station.add_row(_row("V-70", "FAIL", key="K-70", sha="d" * 64)) == "new"
    stored = _insert_claiming_first(chain["bench3"], _row("V-70", "PASS", key="K-70", sha="e" * 64))
    assert stored["first_indexing"] is False
    listed = HistoryStore(chain["owner"]).list()
    assert [(r.verdict, r.changes) for r in listed] == [("FAIL", 1)]
    assert "says it is" not in _verify(chain["owner"]).stdout


def test_two_stations_indexing_one_test_at_once_cannot_both_be_its_first(chain: dict[str, str]) -> None:
    """bench4 indexes a test and has not committed yet when bench3 indexes the same test with other content: the
    test's lock makes bench3 wait, then see bench4's row (refused: another station's test), not both rows stand."""
    import threading

    first = psycopg.connect(_dsn(chain["bench4"]))
    first.execute(_INSERT, {"id": None, "record_manifest": None, "indexed_at": None, "db_login": None,
                            **_row("V-71", "FAIL", key="K-71", sha="f" * 64)})
    outcome: list[BaseException | dict] = []

    def second() -> None:
        try:
            outcome.append(_raw_insert(chain["bench3"], _row("V-71", "PASS", key="K-71", sha="0" * 64)))
        except psycopg.Error as exc:
            outcome.append(exc)

    thread = threading.Thread(target=second)
    thread.start()
    # bench3 is waiting on the test's lock, not done (each poll its own transaction: a transaction sees one snapshot
    # of pg_stat_activity)
    with psycopg.connect(_dsn(chain["owner"]), autocommit=True) as watcher:
        for _ in range(600):
            if watcher.execute("SELECT count(*) FROM pg_stat_activity WHERE usename = 'bench3' AND "
                               "wait_event_type = 'Lock'").fetchone()[0]:
                break
            thread.join(0.05)
        else:
            pytest.fail(f"bench3's insert did not wait for bench4's ({outcome})")
    first.commit()
    first.close()
    thread.join(30)
    assert len(outcome) == 1 and isinstance(outcome[0], psycopg.errors.InsufficientPrivilege), outcome
    listed = HistoryStore(chain["owner"]).list()
    assert [(r.verdict, r.station) for r in listed] == [("FAIL", "Werkstatt Süd 4")]


def test_a_sqlite_row_forged_as_a_tests_first_indexing_is_named_by_verify(tmp_path: Path) -> None:
    """A station's own file: a PASS re-index written with the program's own chain code, claiming to be the first
    (the chain holds: the station computed it). --verify names the row every time."""
    from edc_bench.history.chain import row_hash

    path = tmp_path / "history.sqlite"
    url = f"sqlite:///{path}"
    with HistoryStore(url) as store:
        store.add_row({**_row("V-72", "FAIL", key="K-72", sha="1" * 64), "station": "bench1"})
        stored = store.list()[0]
    with sqlite3.connect(path) as conn:
        conn.row_factory = sqlite3.Row
        last = dict(conn.execute("SELECT * FROM tests ORDER BY id DESC LIMIT 1").fetchone())
        forged = {**last, "id": last["id"] + 1, "verdict": "PASS", "record_sha256": "2" * 64, "first_indexing": 1,
                  "prev_hash": last["row_hash"], "row_hash": None}
        forged["row_hash"] = row_hash("tests", forged["prev_hash"], {**forged, "first_indexing": True})
        conn.execute(f"INSERT INTO tests ({', '.join(forged)}) VALUES ({', '.join('?' * len(forged))})",
                     list(forged.values()))
    assert stored.verdict == "FAIL"
    for _ in range(2):
        found = _verify(url)
        assert found.returncode == 16
        assert f"tests row {forged['id']} says it is the first indexing of its test, but an earlier row indexed it" \
            in found.stdout, found.stdout
        assert "was edited" not in found.stdout  # the chain itself holds: the value is what is wrong


# --- a record tampered with and indexed again, on both databases --------------------------------------------------


# on PostgreSQL in CI's slow pass (the default suite's 5 minutes): the same readers, the same refusals
@pytest.fixture(params=["sqlite", pytest.param("postgresql", marks=pytest.mark.slow)])
def station_url(request: pytest.FixtureRequest, tmp_path: Path) -> str:
    if request.param == "sqlite":
        return f"sqlite:///{tmp_path / 'history.sqlite'}"
    return request.getfixturevalue("chain")["bench3"]


def _rewrite(folder: Path, change: Callable[[dict], None]) -> None:
    """Change record.json and write its integrity manifest again, as an attacker with the code would."""
    doc = json.loads((folder / "record.json").read_text())
    change(doc)
    if "integrity" in doc:
        doc["integrity"] = manifest({k: v for k, v in doc.items() if k != "integrity"}, folder,
                                    list(doc["integrity"]["files"]))
    (folder / "record.json").write_text(json.dumps(doc))


def _indexed_then_changed(fail_dir: Path, tmp_path: Path, url: str, change: Callable[[dict], None]) -> Path:
    folder = tmp_path / "record"
    shutil.copytree(fail_dir, folder)
    assert edc_bench("history", "--add", str(folder), "--db", url).returncode == 0
    _rewrite(folder, change)
    return folder


def _verify_says(url: str, *words: str) -> None:
    for _ in range(2):  # every time, not once
        found = _verify(url)
        assert found.returncode == 16, found.stderr
        assert all(word in found.stdout for word in words), found.stdout


def test_a_tampered_verdict_is_refused_by_every_reader_and_named_by_verify(fail_dir: Path, tmp_path: Path,
                                                                          station_url: str) -> None:
    folder = _indexed_then_changed(fail_dir, tmp_path, station_url, lambda doc: doc.update(verdict="PASS"))
    for argv in (("history", "--add", str(folder), "--db", station_url), ("report", str(folder), "--db", station_url)):
        refused = edc_bench(*argv)
        assert refused.returncode == 2 and "its verdict PASS does not follow from its own figures" in refused.stderr
    classified = edc_bench("classify", str(folder), env={**os.environ, "EDC_BENCH_HISTORY_URL": station_url})
    assert classified.returncode == 13 and "NOT as recorded: the record says PASS, classify says FAIL" in \
        classified.stdout
    assert [r["verdict"] for r in json.loads(edc_bench("history", "--json", "--db", station_url).stdout)] == ["FAIL"]
    _verify_says(station_url, "altered: test", "record.json")


def test_a_record_changed_and_indexed_again_is_a_change_every_reader_shows(fail_dir: Path, tmp_path: Path,
                                                                           station_url: str) -> None:
    """A change the record's own figures cannot show (who tested): the history's first indexing can."""
    folder = _indexed_then_changed(fail_dir, tmp_path, station_url,
                                   lambda doc: doc["identity"].update(operator="somebody else"))
    again = edc_bench("history", "--add", str(folder), "--db", station_url)
    assert again.returncode == 0 and "1 indexed before with other content: each recorded as a change" in again.stderr
    listing = json.loads(edc_bench("history", "--json", "--db", station_url).stdout)
    assert [(r["operator"], r["changes"]) for r in listing] == [(load_record(fail_dir).identity.operator, 1)]
    valve = listing[0]["valve_id"]
    audit = json.loads(edc_bench("history", "--audit", valve, "--json", "--db", station_url).stdout)
    assert [e["event"] for e in audit] == ["test indexed", "record changed after its first indexing (the first "
                                                            "stands)"]
    _verify_says(station_url, "altered: test", "changed: test", "indexed again with other content")
    refused = edc_bench("report", str(folder), "--db", station_url)
    assert refused.returncode == 2 and "is not the record the history first indexed" in refused.stderr
    classified = edc_bench("classify", str(folder), env={**os.environ, "EDC_BENCH_HISTORY_URL": station_url})
    assert classified.returncode == 13 and "is not the record the history first indexed" in classified.stdout


def test_the_schema_downgrade_trick_is_refused_by_the_reader_and_named_by_verify(fail_dir: Path, tmp_path: Path,
                                                                                station_url: str) -> None:
    def downgrade(doc: dict) -> None:
        doc.update(schema=4, verdict="PASS")
        del doc["integrity"]  # then no digest would be checked at all

    folder = _indexed_then_changed(fail_dir, tmp_path, station_url, downgrade)
    for argv in (("history", "--add", str(folder)), ("report", str(folder))):
        refused = edc_bench(*argv, "--db", station_url)
        assert refused.returncode == 2 and "integrity manifest (removed: its schema says 4" in refused.stderr
    _verify_says(station_url, "altered: test", "record.json")


@pytest.mark.slow  # seconds: CI's slow pass runs it (the default suite stays under 5 minutes on CI)
def test_the_report_prints_the_tests_chain_hash_on_the_customers_page(fail_dir: Path, tmp_path: Path) -> None:
    from pdfminer.high_level import extract_text

    url = f"sqlite:///{tmp_path / 'history.sqlite'}"
    folder = tmp_path / "record"
    shutil.copytree(fail_dir, folder)
    assert edc_bench("history", "--add", str(folder), "--db", url).returncode == 0
    drawn = edc_bench("report", str(folder), "--db", url)
    assert drawn.returncode == 0, drawn.stderr
    with HistoryStore(url) as store:
        head = store.heads()[0]
    page_1 = extract_text(str(folder / "report.pdf"), page_numbers=[0])
    assert f"history test {head.id}, chain {head.row_hash[:16]}" in page_1


def test_a_withdrawn_tests_copy_stays_withdrawn(fail_dir: Path, tmp_path: Path, station_url: str) -> None:
    folder, copy = tmp_path / "record", tmp_path / "share" / "record"
    shutil.copytree(fail_dir, folder)
    assert edc_bench("history", "--add", str(folder), "--db", station_url).returncode == 0
    withdraw_url = station_url if station_url.startswith("sqlite") else station_url.replace("bench3@", "ines@")
    listed = json.loads(edc_bench("history", "--json", "--db", station_url).stdout)
    withdrawn = edc_bench("history", "--withdraw", str(listed[0]["id"]), "--why", "valve id typed wrong", "--db",
                          withdraw_url)
    assert withdrawn.returncode == 0, withdrawn.stderr
    shutil.copytree(folder, copy)  # "copy the records to the share" (docs/shop-network.md)
    added = edc_bench("history", "--add", str(copy), "--db", station_url)
    assert added.returncode == 0 and "withdrawn before, and not indexed again" in added.stderr
    assert json.loads(edc_bench("history", "--json", "--db", station_url).stdout) == []


def _add_all(url: str, folders: list[Path]) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "edc_bench", "history", "--add", *map(str, folders), "--db", url],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


@pytest.mark.slow  # seconds: CI's slow pass runs it (the default suite stays under 5 minutes on CI)
def test_four_concurrent_adds_of_the_same_folders_store_each_test_once(fail_dir: Path, tmp_path: Path,
                                                                        station_url: str) -> None:
    folders = []
    for n in range(12):
        folder = tmp_path / f"r{n:02d}"
        shutil.copytree(fail_dir, folder)
        doc = json.loads((folder / "record.json").read_text())
        doc["test_id"] = uuid.uuid4().hex  # twelve tests (twelve valves: one valve at one second is one test)
        doc["valve_id"] = f"V-{n:02d}"
        doc["integrity"] = manifest({k: v for k, v in doc.items() if k != "integrity"}, folder,
                                    list(doc["integrity"]["files"]))
        (folder / "record.json").write_text(json.dumps(doc))
        folders.append(folder)
    procs = [_add_all(station_url, folders) for _ in range(4)]
    outs = [proc.communicate(timeout=240) for proc in procs]
    assert [proc.returncode for proc in procs] == [0] * 4, [err for _, err in outs]
    with HistoryStore(station_url) as store:
        rows = store.list()
        assert len(rows) == 12 and all(r.changes == 0 for r in rows)
        assert store.chain_breaks() == []
    with sa.create_engine(station_url).connect() as conn:
        assert conn.exec_driver_sql("SELECT count(*) FROM tests").scalar() == 12  # not 17 to 22


# --- a station's own SQLite file, changed with the sqlite3 program ----------------------------------------------


def test_dropped_sqlite_triggers_are_restored_said_loudly_and_the_edits_named(fail_dir: Path, tmp_path: Path) -> None:
    path = tmp_path / "history.sqlite"
    url = f"sqlite:///{path}"
    with HistoryStore(url) as store:
        for n in range(4):
            store.add_row({**_row(f"V-7{n}", sha=f"{n}" * 64), "station": "bench1"})
    heads = tmp_path / "heads.json"
    assert edc_bench("history", "--heads", str(heads), "--db", url).returncode == 0
    with sqlite3.connect(path) as conn:
        names = [r[0] for r in conn.execute("SELECT name FROM sqlite_master WHERE type = 'trigger'")]
        for name in names:
            conn.execute(f"DROP TRIGGER {name}")
        conn.execute("UPDATE tests SET verdict = 'PASS' WHERE valve_id = 'V-71'")
        conn.execute("DELETE FROM tests WHERE valve_id = 'V-72'")
        conn.execute("DELETE FROM tests WHERE valve_id = 'V-73'")  # the last row: no later row's link shows it
    listing = edc_bench("history", "--db", url)
    assert listing.returncode == 0
    assert "its append-only triggers were missing or changed (25" in listing.stderr and "restored now" in \
        listing.stderr
    assert "its chain is broken" in listing.stderr
    with sqlite3.connect(path) as conn:
        assert {r[0] for r in conn.execute("SELECT name FROM sqlite_master WHERE type = 'trigger'")} == set(names)
        with pytest.raises(sqlite3.IntegrityError, match="append-only"):
            conn.execute("DELETE FROM tests")
        with pytest.raises(sqlite3.IntegrityError, match="chained"):
            conn.execute("INSERT INTO tests (record_dir, started_at, valve_id, pump_serial, variant, part_number, "
                         "verdict, station, operator, clock, software_version, reason) VALUES ('/x', 'x', 'V', 'P', "
                         "'v', 'p', 'PASS', 'bench1', 'a', 'c', 's', '')")
    found = _verify(url, "--heads", str(heads))
    assert found.returncode == 16
    assert "triggers were found missing or changed and restored" in found.stdout  # kept: every --verify says it
    assert "row 2 of tests (chain bench1): its content no longer gives its hash" in found.stdout
    assert "row 4 of tests" in found.stdout and "gone since its head was kept" in found.stdout  # the deleted tail


def test_a_later_opening_in_the_same_process_checks_the_rows_added_since(tmp_path: Path,
                                                                        monkeypatch: pytest.MonkeyPatch) -> None:
    """A session opens the history for every test: the chain is checked in full at a process's first opening, then
    only in the rows added since (a year's rows took 0.4-0.7 s an opening). A row edited among those, its triggers
    put back exactly as they were, is still named at the next opening; --verify checks everything."""
    path = tmp_path / "history.sqlite"
    url = f"sqlite:///{path}"
    with HistoryStore(url) as store:
        for n in range(3):
            store.add_row({**_row(f"V-8{n}", sha=f"{n}" * 64), "station": "bench1"})
    with HistoryStore(url) as store:  # checked up to row 3 now
        assert store.problems == []
        store.add_row({**_row("V-83", sha="3" * 64), "station": "bench1"})
    with sqlite3.connect(path) as conn:  # row 4 edited, every trigger made again as it was
        triggers = list(conn.execute("SELECT name, sql FROM sqlite_master WHERE type = 'trigger'"))
        for name, _ in triggers:
            conn.execute(f"DROP TRIGGER {name}")
        conn.execute("UPDATE tests SET verdict = 'PASS' WHERE valve_id = 'V-83'")
        for _, sql in triggers:
            conn.execute(sql)
    import edc_bench.history.store as store_module

    checked: dict[str, list[int]] = {}
    real_check = store_module.check_chain

    def spy(table, rows, *args, **kwargs):
        checked[table] = [row["id"] for row in rows]
        return real_check(table, rows, *args, **kwargs)

    monkeypatch.setattr(store_module, "check_chain", spy)
    said: list[str] = []
    with HistoryStore(url, warn=said.append) as store:
        assert any("its chain is broken in 1 place(s), first row 4 of tests" in line for line in said), said
    assert checked["tests"] == [4]  # only the row added since the last opening
    assert _verify(url).returncode == 16


def test_a_sqlite_history_rewritten_whole_is_caught_by_the_heads_kept_outside(tmp_path: Path) -> None:
    path = tmp_path / "history.sqlite"
    url = f"sqlite:///{path}"
    with HistoryStore(url) as store:
        store.add_row({**_row("V-80", "FAIL"), "station": "bench1"})
    heads = tmp_path / "heads.json"
    assert edc_bench("history", "--heads", str(heads), "--db", url).returncode == 0
    path.unlink()
    with HistoryStore(url) as store:  # the same test rebuilt with the program's own code, as PASS
        store.add_row({**_row("V-80", "PASS"), "station": "bench1"})
    alone = _verify(url)
    assert "the chain: holds" in alone.stderr and "chain:" not in alone.stdout  # consistent in itself...
    found = _verify(url, "--heads", str(heads))
    assert found.returncode == 16 and "not the row it was since its head was kept" in found.stdout  # ...not outside


# --- adoption is the chain's ------------------------------------------------------------------------------------


def test_an_adoption_that_bypasses_the_chain_is_refused_and_the_chains_model_stands(chain: dict[str, str],
                                                                                      tmp_path: Path) -> None:
    import os

    from edc_bench.verdict.classifier import packaged_model_path

    station_pc = {**os.environ, "EDC_BENCH_HISTORY_URL": chain["bench3"],
                  "EDC_BENCH_DATA_DIR": str(tmp_path / "station")}
    candidate = packaged_model_path("valve_linear.onnx")  # another network than the shipped one
    bypass = edc_bench("train", "--adopt", str(candidate), "--db", f"sqlite:///{tmp_path / 'any.sqlite'}",
                       env=station_pc)
    assert bypass.returncode == 2 and len(bypass.stderr.strip().splitlines()) == 1, bypass.stderr
    assert "adopted there, by an engineer's login (a member of edc_engineer)" in bypass.stderr
    assert not (tmp_path / "station" / "models").exists() and not (tmp_path / "any.sqlite").exists()
    # the engineer adopts on the chain (on another PC): the row names the station as the chain knows it
    engineer_pc = {**station_pc, "EDC_BENCH_DATA_DIR": str(tmp_path / "engineer-pc")}
    adopted = edc_bench("train", "--adopt", str(candidate), "--by", "someone", "--db", chain["ines"],
                        env=engineer_pc)
    assert adopted.returncode == 0, adopted.stderr
    with sa.create_engine(chain["owner"]).connect() as conn:
        row = conn.exec_driver_sql("SELECT station, adopted_by, db_login FROM adoptions").one()
    assert tuple(row) == ("Werkstatt Nord 3", "Ines Braun", "ines")
    # this station still has the shipped network: it may not judge with it while the chain says otherwise
    refused = edc_bench("test", "--valve-id", "V-1", env=station_pc)
    assert refused.returncode == 2 and "not the one the chain records for station 'Werkstatt Nord 3'" in refused.stderr
    assert len(refused.stderr.strip().splitlines()) == 1


# --- what a review found next (as an attacker would): each one a test -------------------------------------------


def test_a_stations_temporary_tables_cannot_stand_in_for_the_chains(chain: dict[str, str]) -> None:
    """A station may make no temporary table (--setup-roles revokes it); and given one anyway, the trigger does not
    read it: its names are qualified and its search path pinned."""
    with psycopg.connect(_dsn(chain["bench3"])) as conn:
        with pytest.raises(psycopg.errors.InsufficientPrivilege):
            conn.execute("CREATE TEMP TABLE edc_logins (id int, login text, station text, person text)")
    with psycopg.connect(_dsn(chain["owner"]), autocommit=True) as conn:  # as if the right had been left
        conn.execute(f"GRANT TEMPORARY ON DATABASE {chain['owner'].rsplit('/', 1)[1]} TO bench3")
    with psycopg.connect(_dsn(chain["bench3"]), row_factory=psycopg.rows.dict_row) as conn:
        conn.execute("CREATE TEMP TABLE edc_logins (id int, login text, station text, person text)")
        conn.execute("INSERT INTO edc_logins VALUES (99, 'bench3', 'Werkstatt Süd 4', NULL)")
        conn.execute("CREATE TEMP VIEW pg_roles AS SELECT 'bench3'::name AS rolname, true AS rolsuper")
        stored = conn.execute(_INSERT, {"id": -5, "record_manifest": None, "indexed_at": None, "db_login": None,
                                        **_row("V-temp")}).fetchone()
    assert stored["station"] == "Werkstatt Nord 3" and stored["id"] > 0


def test_a_station_can_neither_lock_another_stations_chain_nor_take_ids(chain: dict[str, str]) -> None:
    with psycopg.connect(_dsn(chain["bench3"])) as conn:
        for sql in ("SELECT * FROM chain_heads FOR UPDATE", "SELECT nextval('tests_id_seq')"):
            with pytest.raises(psycopg.errors.InsufficientPrivilege):
                conn.execute(sql)
            conn.rollback()
        # the advisory lock an earlier trigger took is no lock of the chain's now
        conn.execute("SELECT pg_advisory_lock(hashtextextended('edc-bench chain tests Werkstatt Süd 4', 0))")
        with HistoryStore(chain["bench4"]) as other:
            assert other.add_row(_row("V-not-blocked")) == "new"


def test_rows_are_added_at_read_committed_only(chain: dict[str, str]) -> None:
    with psycopg.connect(_dsn(chain["bench3"])) as conn:
        conn.execute("SET TRANSACTION ISOLATION LEVEL REPEATABLE READ")
        with pytest.raises(psycopg.errors.InsufficientPrivilege, match="READ COMMITTED"):
            conn.execute(_INSERT, {"id": None, "record_manifest": None, "indexed_at": None, "db_login": None,
                                   **_row("V-rr")})


def test_an_engineer_files_a_finding_only_as_itself(chain: dict[str, str]) -> None:
    with HistoryStore(chain["bench3"]) as station:
        station.add_row(_row("V-9"))
    with HistoryStore(chain["ines"]) as engineer:
        finding = engineer.add_teardown("V-9", "worn", labelled_by="Chief Engineer Weber", labelled_at="2026-11-20")
    assert finding.recorded_by == "Ines Braun" and finding.labelled_by == "Chief Engineer Weber"
    audit = json.loads(edc_bench("history", "--audit", "V-9", "--json", "--db", chain["owner"]).stdout)
    assert [(e["event"], e["by"]) for e in audit][-1] == ("finding recorded", "Ines Braun")
    assert "opened 2026-11-20 by Chief Engineer Weber" in audit[-1]["what"]


@pytest.mark.slow  # seconds: CI's slow pass runs it (the default suite stays under 5 minutes on CI)
def test_a_withdrawn_tests_copy_stripped_to_look_old_stays_withdrawn(fail_dir: Path, tmp_path: Path,
                                                                     station_url: str) -> None:
    folder = tmp_path / "record"
    shutil.copytree(fail_dir, folder)
    assert edc_bench("history", "--add", str(folder), "--db", station_url).returncode == 0
    withdraw_url = station_url if station_url.startswith("sqlite") else station_url.replace("bench3@", "ines@")
    listed = json.loads(edc_bench("history", "--json", "--db", station_url).stdout)
    assert edc_bench("history", "--withdraw", str(listed[0]["id"]), "--why", "wrong valve", "--db",
                     withdraw_url).returncode == 0
    copy = tmp_path / "copy"
    shutil.copytree(folder, copy)

    def look_old(doc: dict) -> None:  # every sign of a manifest-writing edc-bench removed
        for key in ("integrity", "test_id", "retest"):
            doc.pop(key, None)
        for key in list(doc.get("stop") or {}):
            if "half_width" in key:
                del doc["stop"][key]
        (doc.get("identification") or {}).get("model_fit", {}).pop("core_shift_rel", None)
        doc.update(schema=4, software_version="0.1.0")

    _rewrite(copy, look_old)
    added = edc_bench("history", "--add", str(copy), "--db", station_url)
    assert "withdrawn before, and not indexed again" in added.stderr, added.stderr
    assert json.loads(edc_bench("history", "--json", "--db", station_url).stdout) == []


def test_sqlite_triggers_replaced_by_ones_that_do_nothing_are_made_again(tmp_path: Path) -> None:
    path = tmp_path / "history.sqlite"
    url = f"sqlite:///{path}"
    with HistoryStore(url) as store:
        store.add_row({**_row("V-90"), "station": "bench1"})
    with sqlite3.connect(path) as conn:
        for name in ("tests_no_update", "tests_no_delete"):
            conn.execute(f"DROP TRIGGER {name}")
            conn.execute(f"CREATE TRIGGER {name} BEFORE {name.split('_')[-1].upper()} ON tests BEGIN SELECT 1; END")
    listing = edc_bench("history", "--db", url)
    assert "missing or changed (2: tests_no_update, tests_no_delete)" in listing.stderr
    with sqlite3.connect(path) as conn, pytest.raises(sqlite3.IntegrityError, match="append-only"):
        conn.execute("DELETE FROM tests")


def test_a_negative_zero_is_no_false_alarm(tmp_path: Path) -> None:
    with HistoryStore(f"sqlite:///{tmp_path / 'h.sqlite'}") as store:
        store.add_row({**_row("V-0"), "station": "bench1", "af_rel": -0.0})
        assert store.chain_breaks() == []


@pytest.mark.slow  # seconds: CI's slow pass runs it (the default suite stays under 5 minutes on CI)
def test_an_adoption_made_out_of_the_chains_sight_is_refused_before_a_test_and_named_by_verify(
        chain: dict[str, str], tmp_path: Path) -> None:
    from edc_bench.verdict.classifier import packaged_model_path

    station_pc = {**os.environ, "EDC_BENCH_DATA_DIR": str(tmp_path / "station")}
    station_pc.pop("EDC_BENCH_HISTORY_URL", None)  # the chain's URL left out of this one command
    adopted = edc_bench("train", "--adopt", str(packaged_model_path("valve_linear.onnx")), "--db",
                        f"sqlite:///{tmp_path / 'any.sqlite'}", env=station_pc)
    assert adopted.returncode == 0, adopted.stderr
    # the chain records no adoption for the station: it judges with the shipped default there, and a test says so
    with_chain = {**station_pc, "EDC_BENCH_HISTORY_URL": chain["bench3"]}
    refused = edc_bench("test", "--valve-id", "V-1", env=with_chain)
    assert refused.returncode == 2 and "records no adoption of for station 'Werkstatt Nord 3'" in refused.stderr
    spelled_otherwise = edc_bench("test", "--valve-id", "V-1", "--db", chain["bench3"] + "?application_name=x",
                                  env=station_pc)
    assert spelled_otherwise.returncode == 2 and "records no adoption" in spelled_otherwise.stderr
    # tested without the history, then indexed into it: --verify names the test's model
    out = tmp_path / "records"
    tested = edc_bench("test", "--valve-id", "V-1", "--no-history", "--no-figure", "--out", str(out), env=with_chain)
    assert tested.returncode in (0, 10, 11), tested.stderr
    assert edc_bench("history", "--add", *map(str, out.iterdir()), "--db", chain["bench3"]).returncode == 0
    found = _verify(chain["bench3"], "--station", "Werkstatt Nord 3")
    assert found.returncode == 16 and "model: test" in found.stdout and "no adoption" in found.stdout


def test_a_sqlite_row_edited_in_place_is_the_one_a_valves_page_calls_altered(tmp_path: Path) -> None:
    """The web view's ALTERED mark (HistoryStore.altered_tests) on a station's own file: the edited row, no other."""
    path = tmp_path / "history.sqlite"
    url = f"sqlite:///{path}"
    with HistoryStore(url) as store:
        for valve in ("V-90", "V-91", "V-92"):
            store.add_row({**_row(valve, "FAIL"), "station": "bench1"})
        ids = [int(r.id) for r in store.list()]
        assert store.altered_tests(ids) == set()
    with sqlite3.connect(path) as conn:
        conn.execute("DROP TRIGGER tests_no_update")
        conn.execute("UPDATE tests SET verdict = 'PASS' WHERE valve_id = 'V-91'")
    with HistoryStore(url, warn=lambda _problem: None) as store:
        assert store.altered_tests(ids) == {ids[1]}
