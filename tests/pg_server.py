"""A PostgreSQL server of the tests' own (started from the machine's PostgreSQL programs; skipped where there are
none) and a fresh database on it for each test, at this edc-bench's schema revision."""

from __future__ import annotations

import contextlib
import os
import subprocess
import uuid
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest
import sqlalchemy as sa

from edc_bench.history import migrate
from edc_bench.testing.postgres import as_postgres_user, pg_program, temporary_postgres

#: the names tests/history/test_shop_network_doc.py uses (the server's programs, run as the postgres user)
_pg_bin, _as_postgres_user = pg_program, as_postgres_user

# --- a PostgreSQL server of the tests' own, where the machine has one ------------------------------------------


@pytest.fixture(scope="session")
def postgres_url() -> Iterator[str]:
    if not (pg_program("initdb") and pg_program("pg_ctl")):
        pytest.skip("PostgreSQL server programs (initdb, pg_ctl) are not installed on this machine")
    if os.geteuid() == 0 and subprocess.run(["id", "postgres"], capture_output=True).returncode != 0:
        pytest.skip("running as root and there is no 'postgres' user to run the server as")
    with contextlib.ExitStack() as stack:
        try:
            url = stack.enter_context(temporary_postgres())
        except RuntimeError as exc:  # initdb failed, or the server did not start
            pytest.skip(f"PostgreSQL here: {exc}")
        yield url


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


