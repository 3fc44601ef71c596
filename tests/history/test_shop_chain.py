"""A shop's shared history that holds up: roles in the database, append-only, the audit trail, the schema's
revisions, --verify, and a password never shown."""

from __future__ import annotations

import datetime as dt
import json
import os
import shutil
import socket
from collections.abc import Callable
from pathlib import Path

import psycopg
import pytest
import sqlalchemy as sa
from helpers import edc_bench

from edc_bench.bench import run_simulated_test
from edc_bench.config import load_variant
from edc_bench.errors import ConfigError
from edc_bench.history import migrate
from edc_bench.history.store import HistoryStore
from edc_bench.records.reader import load_record
from edc_bench.records.record import write_record


@pytest.fixture(scope="module")
def record_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """One simulated test's record folder (PASS)."""
    return write_record(run_simulated_test(load_variant(), "new", 3), tmp_path_factory.mktemp("records"),
                        figure=False)


def _login_url(server_db_url: str, login: str) -> str:
    """The same database as another login (the tests' server trusts every local login)."""
    return server_db_url.replace("://postgres@", f"://{login}@")


def _create_login(server_db_url: str, login: str, role: str) -> str:
    engine = sa.create_engine(server_db_url)
    with engine.begin() as conn:
        conn.exec_driver_sql(f"DO $$ BEGIN IF NOT EXISTS (SELECT FROM pg_roles WHERE rolname = '{login}') THEN "
                             f"CREATE ROLE {login} LOGIN; END IF; END $$")
        conn.exec_driver_sql(f"GRANT {role} TO {login}")
    engine.dispose()
    if role == "edc_station":  # the chain's owner says which station the login is (docs/shop-network.md)
        with HistoryStore(server_db_url) as owner:
            owner.map_login(login, login, None, "admin")
    return _login_url(server_db_url, login)


@pytest.mark.slow  # the default suite's 5 minutes; CI's slow pass runs it
def test_roles_hold_in_the_database_itself(postgres_db: str, record_dir: Path, tmp_path: Path) -> None:
    roles = edc_bench("history", "--setup-roles", "--db", postgres_db)
    assert roles.returncode == 0 and "edc_station" in roles.stdout, roles.stderr
    station = _create_login(postgres_db, "bench3", "edc_station")
    engineer = _create_login(postgres_db, "ines", "edc_engineer")

    # a station adds tests and reads
    added = edc_bench("history", "--add", str(record_dir), "--db", station)
    assert added.returncode == 0 and "indexed 1 new" in added.stderr, added.stderr
    valve = load_record(record_dir).valve_id
    # ... and may not label, withdraw, adopt or set roles: one line naming whose login may
    env = {**os.environ, "EDC_BENCH_DATA_DIR": str(tmp_path / "station")}
    for argv, words in (
            (("label", valve, "--finding", "worn"), "may not record teardown findings: ask the engineer's login"),
            (("history", "--withdraw", "1", "--why", "wrong valve"), "may not withdraw tests or findings"),
            (("train", "--adopt", "shipped"), "may not record model adoptions"),
            (("history", "--setup-roles"), "may not create the history's roles: ask the database's owner")):
        proc = edc_bench(*argv, "--db", station, env=env)
        assert proc.returncode == 2, (argv, proc.stdout, proc.stderr)
        assert words in proc.stderr and "bench3" in proc.stderr, proc.stderr
        assert len(proc.stderr.strip().splitlines()) == 1 and "Traceback" not in proc.stderr
    assert not (tmp_path / "station" / "models").exists()  # the refused adoption changed nothing on the station

    # a direct UPDATE or DELETE of a test as the station's login fails in the database
    dsn = station.replace("postgresql+psycopg://", "postgresql://")
    with psycopg.connect(dsn) as conn:
        for sql in ("UPDATE tests SET verdict = 'FAIL'", "DELETE FROM tests", "INSERT INTO teardowns (valve_id, "
                    "finding, note, labelled_by, labelled_at, recorded_at) VALUES ('V', 'worn', '', 'x', 'd', 'd')"):
            with pytest.raises(psycopg.errors.InsufficientPrivilege):
                conn.execute(sql)
            conn.rollback()

    # the engineer labels and withdraws; the audit names the database login
    labelled = edc_bench("label", valve, "--finding", "worn", "--by", "ines", "--db", engineer)
    assert labelled.returncode == 0, labelled.stderr
    withdrawn = edc_bench("history", "--withdraw", "1", "--why", "valve id typed wrong", "--db", engineer)
    assert withdrawn.returncode == 0, withdrawn.stderr
    audit = json.loads(edc_bench("history", "--audit", valve, "--json", "--db", station).stdout)
    assert [(e["event"], e["db_login"]) for e in audit] == [
        ("test indexed", "bench3"), ("finding recorded", "ines"), ("test 1 withdrawn", "ines")]
    assert audit[2]["what"] == "valve id typed wrong"
    listing = json.loads(edc_bench("history", "--json", "--db", station).stdout)
    assert listing == []  # withdrawn: no longer counted

    # the owner's plain UPDATE, DELETE, TRUNCATE hit the triggers too
    with psycopg.connect(postgres_db.replace("postgresql+psycopg://", "postgresql://")) as conn:
        for sql in ("UPDATE tests SET verdict = 'FAIL'", "DELETE FROM amendments", "TRUNCATE teardowns"):
            with pytest.raises(psycopg.errors.RaiseException, match="append-only"):
                conn.execute(sql)
            conn.rollback()


@pytest.mark.slow  # seconds: CI's slow pass runs it (the default suite stays under 5 minutes on CI)
def test_a_database_owner_that_is_no_superuser_sets_the_chain_up(postgres_url: str, record_dir: Path) -> None:
    """docs/shop-network.md's steps: an owner login with CREATEROLE, its own database, --upgrade, --setup-roles."""
    admin = sa.create_engine(postgres_url, isolation_level="AUTOCOMMIT")
    name = f"chain_{os.getpid()}"
    with admin.connect() as conn:
        conn.exec_driver_sql("DO $$ BEGIN IF NOT EXISTS (SELECT FROM pg_roles WHERE rolname = 'edc_admin') THEN "
                             "CREATE ROLE edc_admin LOGIN CREATEROLE; END IF; END $$")
        conn.exec_driver_sql(f"CREATE DATABASE {name} OWNER edc_admin")
    admin.dispose()
    owner = postgres_url.rsplit("/", 1)[0].replace("://postgres@", "://edc_admin@") + f"/{name}"
    for argv in (("history", "--upgrade"), ("history", "--setup-roles")):
        proc = edc_bench(*argv, "--db", owner)
        assert proc.returncode == 0, (argv, proc.stdout, proc.stderr)
    station = _create_login(owner.replace("://edc_admin@", "://postgres@"), "bench5", "edc_station")
    added = edc_bench("history", "--add", str(record_dir), "--db", station)
    assert added.returncode == 0, added.stderr
    refused = edc_bench("history", "--withdraw", "1", "--why", "x", "--db", station)
    assert refused.returncode == 2 and "may not withdraw" in refused.stderr


@pytest.mark.slow  # seconds: CI's slow pass runs it (the default suite stays under 5 minutes on CI)
def test_the_owner_sees_and_applies_each_schema_change(new_postgres_database: Callable[..., str]) -> None:
    url = new_postgres_database(upgrade=False)
    station = _create_login(url, "bench4", "pg_read_all_data")
    with pytest.raises(ConfigError, match=r"holds no edc-bench history yet: its owner's login runs "
                                          r"'edc-bench history --upgrade' on it first"):
        HistoryStore(station)
    # an older history (before revisions): its rows are kept through the upgrade
    engine = sa.create_engine(url)
    with engine.begin() as conn:
        conn.exec_driver_sql("CREATE TABLE tests (id SERIAL PRIMARY KEY, record_dir VARCHAR(1024) NOT NULL UNIQUE, "
                             "started_at VARCHAR(40) NOT NULL, valve_id VARCHAR(200) NOT NULL, pump_serial "
                             "VARCHAR(200) NOT NULL, variant VARCHAR(200) NOT NULL, part_number VARCHAR(100) NOT "
                             "NULL, verdict VARCHAR(20) NOT NULL, af_v FLOAT, a1_v_s_per_mm FLOAT, af_rel FLOAT, "
                             "a1_rel FLOAT, probability_faulty FLOAT, distance FLOAT, station VARCHAR(200) NOT "
                             "NULL, operator VARCHAR(200) NOT NULL, clock VARCHAR(20) NOT NULL, software_version "
                             "VARCHAR(40) NOT NULL, reason TEXT NOT NULL)")
        conn.exec_driver_sql("INSERT INTO tests (record_dir, started_at, valve_id, pump_serial, variant, "
                             "part_number, verdict, station, operator, clock, software_version, reason) VALUES "
                             "('/r/a', '2026-05-01T08:00', 'V1', 'S', 'p', 'PE', 'PASS', 'st', 'ana', 'sim', "
                             "'0.1', '')")
    engine.dispose()
    with pytest.raises(ConfigError, match="was made by an edc-bench before schema revisions"):
        HistoryStore(url)
    schema = edc_bench("history", "--schema", "--db", url)
    assert schema.returncode == 0 and "schema revision (none)" in schema.stdout
    assert "to apply: 0001" in schema.stdout and "to apply: 0002  Append-only" in schema.stdout, schema.stdout
    upgraded = edc_bench("history", "--upgrade", "--db", url)
    assert upgraded.returncode == 0 and "applied 0002" in upgraded.stdout, upgraded.stderr
    again = edc_bench("history", "--upgrade", "--db", url)
    assert "nothing to apply" in again.stdout
    with HistoryStore(url) as store:
        assert [r.valve_id for r in store.list()] == ["V1"]
        row = {key: value for key, value in store.list()[0].columns().items() if key != "id"}
        store.add_row({**row, "verdict": "FAIL"})  # the test indexed again with other content: a change
        # its first indexing stands, and the change is shown with it
        assert [(r.verdict, r.changes) for r in store.list()] == [("PASS", 1)] and len(store.audit("V1")) == 2
    with sa.create_engine(url).begin() as conn:
        assert migrate.current(conn) == migrate.head()
        conn.exec_driver_sql("ALTER TABLE alembic_version DISABLE TRIGGER ALL")
        conn.exec_driver_sql("UPDATE alembic_version SET version_num = '0099'")  # as a newer edc-bench leaves it
    for argv in (("history",), ("history", "--schema"), ("history", "--upgrade")):
        newer = edc_bench(*argv, "--db", url)
        assert newer.returncode == 2 and "made by a newer edc-bench" in newer.stderr, (argv, newer.stderr)
        assert "Traceback" not in newer.stderr


@pytest.mark.slow  # over 5 s each: the default suite's 5 minutes (CI's slow pass runs it)
def test_sqlite_refuses_changes_and_the_audit_shows_withdrawals_and_corrections(record_dir: Path,
                                                                               tmp_path: Path) -> None:
    url = f"sqlite:///{tmp_path / 'h.sqlite'}"
    folder = tmp_path / "rec"
    shutil.copytree(record_dir, folder)
    assert edc_bench("history", "--add", str(folder), "--db", url).returncode == 0
    valve = load_record(folder).valve_id
    for argv in (("label", valve, "--finding", "worn", "--by", "ana"),
                 ("label", valve, "--finding", "reusable", "--by", "ana", "--corrects", "1"),
                 ("history", "--withdraw", "1", "--why", "tested on the wrong pump", "--by", "ben")):
        proc = edc_bench(*argv, "--db", url)
        assert proc.returncode == 0, (argv, proc.stderr)
    audit = edc_bench("history", "--audit", valve, "--db", url)
    assert audit.returncode == 0
    for words in ("test indexed", "finding recorded", "(corrects finding", "test 1 withdrawn",
                  "tested on the wrong pump", "ben"):
        assert words in audit.stdout, audit.stdout
    engine = sa.create_engine(url)
    with engine.connect() as conn:
        for sql in ("UPDATE tests SET verdict = 'FAIL'", "DELETE FROM tests", "UPDATE teardowns SET finding = 'x'",
                    "DELETE FROM amendments"):
            with pytest.raises(sa.exc.IntegrityError, match="append-only"):
                conn.exec_driver_sql(sql)
    engine.dispose()
    same = edc_bench("history", "--add", str(folder), "--db", url)
    assert "withdrawn before, and not indexed again" in same.stderr  # a withdrawn test stays withdrawn
    for argv, words in ((("label", "--withdraw", "2"), "--why is missing"),
                        (("label", "--withdraw", "2", "--why", "x", "--note", "n"), "--note does not go with it"),
                        (("label", "--withdraw", "2", "--why", "x", "--by", "a\nb"), "--by"),
                        (("label", "--list", "--corrects", "1"), "--corrects ID goes with the finding"),
                        (("history", "--withdraw", "1", "--why", "x", "--json"), "--json does not go with it")):
        proc = edc_bench(*argv, "--db", url)
        assert proc.returncode == 2 and words in proc.stderr, (argv, proc.stderr)
    assert edc_bench("label", "--delete", "2", "--db", url).returncode == 0  # the old spelling: recorded by mistake
    assert "recorded by mistake" in edc_bench("history", "--audit", valve, "--db", url).stdout


def _as_another_test(folder: Path) -> None:
    """Make a copied record folder another test's: its own test id, its manifest written again."""
    import uuid

    from edc_bench.records.integrity import manifest

    doc = json.loads((folder / "record.json").read_text())
    doc["test_id"] = uuid.uuid4().hex
    doc["valve_id"] = f"{doc['valve_id']}-{folder.name}"  # and another valve: the same valve at the same second
    # and place would be the same test (the history's legacy key)
    files = [name for name in doc["integrity"]["files"]]
    doc["integrity"] = manifest({k: v for k, v in doc.items() if k != "integrity"}, folder, files)
    (folder / "record.json").write_text(json.dumps(doc))


def test_verify_finds_a_folder_changed_after_it_was_indexed_and_one_removed(record_dir: Path,
                                                                            tmp_path: Path) -> None:
    url = f"sqlite:///{tmp_path / 'h.sqlite'}"
    kept, changed, gone = (tmp_path / name for name in ("kept", "changed", "gone"))
    for folder in (kept, changed, gone):
        shutil.copytree(record_dir, folder)
        _as_another_test(folder)  # a copy is the same test: three tests here
    assert edc_bench("history", "--add", str(kept), str(changed), str(gone), "--db", url).returncode == 0
    clean = edc_bench("history", "--verify", "--db", url)
    assert clean.returncode == 0 and "checked 3" in clean.stderr and "0 missing, 0 altered" in clean.stderr
    doc = json.loads((changed / "record.json").read_text())
    doc["verdict"] = "FAIL"
    (changed / "record.json").write_text(json.dumps(doc))
    shutil.rmtree(gone)
    found = edc_bench("history", "--verify", "--db", url)
    assert found.returncode == 16, found.stderr
    lines = found.stdout.strip().splitlines()
    assert len(lines) == 2
    assert lines[0].startswith("altered: test 2") and "record.json's 'verdict'" in lines[0]
    assert lines[1].startswith("missing: test 3") and "the record folder is gone" in lines[1]
    assert "1 missing, 1 altered" in found.stderr


PASSWORD = "Pa55-w0rd-8xq"


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.mark.parametrize(("form", "every_command"), [
    pytest.param("userinfo", True, marks=pytest.mark.slow),  # 30 processes: CI's slow pass; the others every run
    pytest.param("userinfo", False, marks=pytest.mark.slow),  # 7 s; tests/history/test_passwords.py every run
    pytest.param("query", False, marks=pytest.mark.slow),
    pytest.param("slash", False, marks=pytest.mark.slow)])
def test_no_command_shows_the_database_password(record_dir: Path, tmp_path: Path, form: str,
                                                every_command: bool) -> None:
    """Every command that reaches the history, the password given in the URL (as user:PASSWORD@, and for a few
    commands as ?password=), by --db and by EDC_BENCH_HISTORY_URL: not in any output, nor in any file written."""
    port = _free_port()  # nothing listens there: every command meets a database that is down
    url = (f"postgresql+psycopg://shop:{PASSWORD}@127.0.0.1:{port}/edc" if form == "userinfo"
           else f"postgresql+psycopg://shop@127.0.0.1:{port}/edc?password={PASSWORD}")
    if form == "slash":  # SQLAlchemy takes '/' and quotes in a password as they are
        url = f"postgresql+psycopg://shop:{PASSWORD}/x'y@127.0.0.1:{port}/edc"
    folder = tmp_path / "rec"
    shutil.copytree(record_dir, folder)
    commands = [("history",), ("history", "--add", str(folder)), ("history", "--audit", "V"), ("history", "--verify"),
                ("history", "--schema"), ("history", "--upgrade"), ("history", "--setup-roles"),
                ("history", "--withdraw", "1", "--why", "x"), ("label", "V", "--finding", "worn"),
                ("label", "--list"), ("train", "--from-history"), ("train", "--adopt", "shipped"),
                ("evaluate", "--from-history"), ("study-boundary", "--from-history"),
                ("test", "--valve", "new", "--no-figure", "--out", str(tmp_path / "out"))]
    if not every_command:
        commands = [commands[0], commands[1], commands[-1]]
    env = {**os.environ, "EDC_BENCH_DATA_DIR": str(tmp_path / "data")}
    for argv in commands:
        for how in ("flag", "environment"):
            flag = ("--db", url) if how == "flag" else ()
            run_env = env if how == "flag" else {**env, "EDC_BENCH_HISTORY_URL": url}
            proc = edc_bench(*argv, *flag, env=run_env, cwd=tmp_path)
            said = proc.stdout + proc.stderr
            assert PASSWORD not in said, (argv, how, said)
            assert proc.returncode in (0, 2), (argv, how, proc.returncode, said)  # done, or refused in one line
            assert "Traceback" not in said and "***" in said, (argv, how, said)
    written = [p for p in tmp_path.rglob("*") if p.is_file()]
    assert any(p.name == "record.json" for p in written)  # the tests ran and wrote their records
    for path in written:
        assert PASSWORD.encode() not in path.read_bytes(), path


def test_the_head_revision_written_in_the_code_is_alembics() -> None:
    from alembic.script import ScriptDirectory

    from edc_bench.history.migrate import HEAD, _config

    assert ScriptDirectory.from_config(_config()).get_current_head() == HEAD


def test_a_test_on_the_simulated_rig_is_marked_and_left_out_of_trends_and_training(record_dir: Path,
                                                                                   tmp_path: Path) -> None:
    from edc_bench.history.store import Filters

    url = f"sqlite:///{tmp_path / 'h.sqlite'}"
    record = load_record(record_dir)
    assert record.simulated_rig
    with HistoryStore(url) as store:
        store.add(record, record_dir)
        rig_row = {key: value for key, value in store.list()[0].columns().items() if key != "id"}
        # a test on a rig a minute after the simulated one (a fixed date stopped being later at midnight)
        later = (dt.datetime.fromisoformat(record.started_at) + dt.timedelta(minutes=1)).isoformat()
        store.add_row({**rig_row, "record_dir": "/records/on-a-rig", "simulated": False, "test_key": "on-a-rig",
                       "legacy_key": "on-a-rig", "started_at": later})
        store.add_teardown(record.valve_id, "worn", labelled_by="ana", labelled_at="2099-01-01")
        assert [r.simulated for r in store.list()] == [True, False]  # listed, and marked
        assert [r.simulated for r in store.list(Filters(simulated=False))] == [False]
        assert [r.record_dir for r in store.trend(record.valve_id)] == ["/records/on-a-rig"]
        assert len(store.trend(record.valve_id, include_simulated=True)) == 2
        assert [m.test.record_dir for m in store.labelled_tests() if m.test is not None] == ["/records/on-a-rig"]
    listing = edc_bench("history", "--db", url)
    assert "sim: 1 on the simulated rig" in " ".join(listing.stdout.split())  # the title wraps with the path's length
    only_simulated = f"sqlite:///{tmp_path / 'sim.sqlite'}"
    assert edc_bench("history", "--add", str(record_dir), "--db", only_simulated).returncode == 0
    refused = edc_bench("history", "--trend", record.valve_id, "--db", only_simulated)
    assert refused.returncode == 2 and "add --include-simulated" in refused.stderr
    shown = edc_bench("history", "--trend", record.valve_id, "--include-simulated", "--db", only_simulated)
    assert shown.returncode == 0 and "1 visit" in shown.stdout
