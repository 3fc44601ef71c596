"""A throw-away PostgreSQL server from the machine's own programs (initdb, pg_ctl): for the web view's benchmark,
which needs a server no shop's data is on."""

from __future__ import annotations

import os
import shutil
import socket
import subprocess
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path


def pg_program(name: str) -> str | None:
    """A PostgreSQL program on the PATH or in Debian's /usr/lib/postgresql/*/bin (the newest)."""
    found = shutil.which(name)
    if found:
        return found
    for base in sorted(Path("/usr/lib/postgresql").glob("*/bin"), reverse=True):
        if (base / name).exists():
            return str(base / name)
    return None


def as_postgres_user(cmd: list[str]) -> list[str]:
    """``cmd`` run as the postgres user when this process is root (the server refuses to run as root)."""
    return ["runuser", "-u", "postgres", "--", *cmd] if os.geteuid() == 0 else cmd


@contextmanager
def temporary_postgres() -> Iterator[str]:
    """A new server on 127.0.0.1 (trust authentication, stopped and removed afterwards); yields its superuser's URL
    (``postgresql+psycopg://postgres@127.0.0.1:PORT/postgres``). Raises RuntimeError where it cannot start."""
    initdb, pg_ctl = pg_program("initdb"), pg_program("pg_ctl")
    if not (initdb and pg_ctl):
        raise RuntimeError("PostgreSQL's initdb and pg_ctl are not installed (Debian: apt-get install postgresql)")
    base = Path(tempfile.mkdtemp(prefix="edc-bench-pg-"))
    if os.geteuid() == 0:
        shutil.chown(base, "postgres")
    data = base / "data"
    try:
        init = subprocess.run(as_postgres_user([initdb, "-D", str(data), "-A", "trust", "-U", "postgres"]),
                              capture_output=True, text=True)
        if init.returncode != 0:
            raise RuntimeError(f"initdb failed: {init.stderr.strip()[-300:]}")
        with socket.socket() as s:
            s.bind(("127.0.0.1", 0))
            port = s.getsockname()[1]
        options = f"-p {port} -k {base} -c listen_addresses=127.0.0.1"
        start = subprocess.run(as_postgres_user([pg_ctl, "-D", str(data), "-o", options, "-l", str(base / "log"), "-w",
                                             "start"]), capture_output=True, text=True)
        if start.returncode != 0:
            raise RuntimeError(f"the server did not start: {start.stderr.strip()[-300:]}")
        try:
            yield f"postgresql+psycopg://postgres@127.0.0.1:{port}/postgres"
        finally:
            subprocess.run(as_postgres_user([pg_ctl, "-D", str(data), "-m", "immediate", "stop"]), capture_output=True)
    finally:
        shutil.rmtree(base, ignore_errors=True)
