"""A PostgreSQL server of the tests' own (started from the machine's PostgreSQL programs; skipped where there are
none) and a fresh database on it for each test, at this edc-bench's schema revision."""

from __future__ import annotations

import os
import shutil
import socket
import subprocess
import tempfile
import uuid
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest
import sqlalchemy as sa

from edc_bench.history import migrate

# --- a PostgreSQL server of the tests' own, where the machine has one ------------------------------------------


def _pg_bin(name: str) -> str | None:
    found = shutil.which(name)
    if found:
        return found
    for base in sorted(Path("/usr/lib/postgresql").glob("*/bin"), reverse=True):
        if (base / name).exists():
            return str(base / name)
    return None


def _as_postgres_user(cmd: list[str]) -> list[str]:
    # the server refuses to run as root; CI and this machine run tests as root
    if os.geteuid() == 0:
        return ["runuser", "-u", "postgres", "--", *cmd]
    return cmd


@pytest.fixture(scope="session")
def postgres_url() -> Iterator[str]:
    initdb, pg_ctl = _pg_bin("initdb"), _pg_bin("pg_ctl")
    if not (initdb and pg_ctl):
        pytest.skip("PostgreSQL server programs (initdb, pg_ctl) are not installed on this machine")
    if os.geteuid() == 0 and subprocess.run(["id", "postgres"], capture_output=True).returncode != 0:
        pytest.skip("running as root and there is no 'postgres' user to run the server as")
    # not under pytest's temp folder: its parents are private to this user, and the server runs as another
    base = Path(tempfile.mkdtemp(prefix="edc-bench-pg-"))
    data = base / "data"
    if os.geteuid() == 0:
        shutil.chown(base, "postgres")
    init = subprocess.run(_as_postgres_user([initdb, "-D", str(data), "-A", "trust", "-U", "postgres"]),
                          capture_output=True, text=True)
    if init.returncode != 0:
        pytest.skip(f"initdb failed here: {init.stderr.strip()[-300:]}")
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    opts = f"-p {port} -k {base} -c listen_addresses=127.0.0.1"
    start = subprocess.run(_as_postgres_user([pg_ctl, "-D", str(data), "-o", opts, "-l", str(base / "log"), "-w",
                                              "start"]), capture_output=True, text=True)
    if start.returncode != 0:
        pytest.skip(f"the PostgreSQL server did not start here: {start.stderr.strip()[-300:]}")
    try:
        yield f"postgresql+psycopg://postgres@127.0.0.1:{port}/postgres"
    finally:
        subprocess.run(_as_postgres_user([pg_ctl, "-D", str(data), "-m", "immediate", "stop"]), capture_output=True)
        shutil.rmtree(base, ignore_errors=True)


def new_database(server_url: str, upgrade: bool = True) -> str:
    """A new, empty database on the tests' server (its owner the superuser); at this edc-bench's revision if
    ``upgrade``. Returns its URL."""
    name = f"h_{uuid.uuid4().hex[:12]}"
    engine = sa.create_engine(server_url, isolation_level="AUTOCOMMIT")
    with engine.connect() as conn:
        conn.exec_driver_sql(f"CREATE DATABASE {name}")
    engine.dispose()
    url = server_url.rsplit("/", 1)[0] + f"/{name}"
    if upgrade:
        engine = sa.create_engine(url)
        migrate.upgrade(engine)
        engine.dispose()
    return url


@pytest.fixture
def new_postgres_database(postgres_url: str) -> Callable[..., str]:
    """:func:`new_database` on the tests' server: ``new_postgres_database(upgrade=False)``."""
    return lambda upgrade=True: new_database(postgres_url, upgrade)


@pytest.fixture
def postgres_db(postgres_url: str) -> str:
    """A new database of the tests' server, at this edc-bench's schema revision (one server for the session)."""
    return new_database(postgres_url)


@pytest.fixture(params=["sqlite", "postgresql"])
def db_url(request: pytest.FixtureRequest, tmp_path: Path) -> Iterator[str]:
    if request.param == "sqlite":
        yield f"sqlite:///{tmp_path / 'history.sqlite'}"
        return
    yield request.getfixturevalue("postgres_db")


