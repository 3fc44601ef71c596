"""docs/shop-network.md's set-up, run as written against a new PostgreSQL server that asks for passwords.

Every code block the page marks ``<!-- doc-test: WHO -->`` is run as that person would: the administrator's SQL
in ``psql`` as the server's superuser, the owner's SQL in ``psql`` with the owner's URL, and each person's shell
lines in ``bash`` with a home folder of their own (their ``~/.pgpass``, their ``~/.profile``, their edc-bench data
folder). The page calls the server ``dbhost``; the tests' server is on this machine, so libpq is told its address
(``PGHOSTADDR``) and port (``PGPORT``): the text of every block is the page's.
"""

from __future__ import annotations

import os
import re
import shutil
import socket
import subprocess
import sys
import tempfile
import textwrap
from collections.abc import Iterator
from pathlib import Path

import pytest
from pg_server import _as_postgres_user, _pg_bin

DOC = Path(__file__).resolve().parents[2] / "docs" / "shop-network.md"
_BLOCK = re.compile(r"<!-- doc-test: (?P<who>[\w-]+) -->\s*\n(?P<indent>[ ]*)```(?P<lang>\w+)\n(?P<body>.*?)```",
                    re.DOTALL)
PASSWORDS = ("owner-Secret-1", "bench3-Secret-1", "ines-Secret-1")


def doc_blocks() -> list[tuple[str, str, str]]:
    """The page's marked blocks in order: (who, language, text)."""
    return [(m["who"], m["lang"], textwrap.dedent(m["body"])) for m in _BLOCK.finditer(DOC.read_text())]


@pytest.fixture(scope="module")
def password_server() -> Iterator[tuple[Path, int]]:
    """A new PostgreSQL server whose TCP logins need a password (scram), as a shop's is; its socket folder and
    port. The superuser reaches it over the socket without one (the administrator's ``sudo -u postgres psql``)."""
    initdb, pg_ctl, psql = _pg_bin("initdb"), _pg_bin("pg_ctl"), _pg_bin("psql")
    if not (initdb and pg_ctl and psql):
        pytest.skip("PostgreSQL's programs (initdb, pg_ctl, psql) are not installed on this machine")
    if os.geteuid() == 0 and subprocess.run(["id", "postgres"], capture_output=True).returncode != 0:
        pytest.skip("running as root and there is no 'postgres' user to run the server as")
    base = Path(tempfile.mkdtemp(prefix="edc-bench-pgdoc-"))
    if os.geteuid() == 0:
        shutil.chown(base, "postgres")
    data = base / "data"
    init = subprocess.run(_as_postgres_user([initdb, "-D", str(data), "-U", "postgres", "--auth-local=trust",
                                             "--auth-host=scram-sha-256"]), capture_output=True, text=True)
    if init.returncode != 0:
        pytest.skip(f"initdb failed here: {init.stderr.strip()[-300:]}")
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    start = subprocess.run(_as_postgres_user([pg_ctl, "-D", str(data), "-o",
                                              f"-p {port} -k {base} -c listen_addresses=127.0.0.1", "-l",
                                              str(base / "log"), "-w", "start"]), capture_output=True, text=True)
    if start.returncode != 0:
        pytest.skip(f"the PostgreSQL server did not start here: {start.stderr.strip()[-300:]}")
    try:
        yield base, port
    finally:
        subprocess.run(_as_postgres_user([pg_ctl, "-D", str(data), "-m", "immediate", "stop"]), capture_output=True)
        shutil.rmtree(base, ignore_errors=True)


@pytest.mark.slow  # a server of its own and every step as a process: CI's slow pass
def test_the_pages_steps_set_a_chain_up_as_written(password_server: tuple[Path, int], tmp_path: Path) -> None:
    socket_dir, port = password_server
    psql = _pg_bin("psql")
    assert psql is not None
    homes = {who: tmp_path / who for who in ("owner", "station", "engineer")}
    for home in homes.values():
        home.mkdir()
    bin_dir = str(Path(sys.executable).parent)  # edc-bench, as installed beside this Python
    base_env = {key: value for key, value in os.environ.items()
                if not key.startswith(("EDC_BENCH_", "PG")) and key != "HOME"}
    base_env.update(PATH=f"{bin_dir}:{base_env.get('PATH', '')}", PGHOSTADDR="127.0.0.1", PGPORT=str(port))

    def env_of(who: str) -> dict[str, str]:
        home = homes[who]
        return {**base_env, "HOME": str(home), "EDC_BENCH_DATA_DIR": str(home / "edc-bench")}

    outputs: list[str] = []
    blocks = doc_blocks()
    assert [who for who, _, _ in blocks] == ["administrator", "owner", "owner", "owner-sql", "owner", "administrator",
                                             "station", "engineer", "station", "engineer"], "the page's steps moved"
    for step, (who, lang, text) in enumerate(blocks, 1):
        script = tmp_path / f"block-{step}.{lang}"
        script.write_text(text)
        if who == "administrator":  # the server's superuser, on the server
            cmd = _as_postgres_user([psql, "-h", str(socket_dir), "-p", str(port), "-U", "postgres", "-d", "postgres",
                                     "-X", "-v", "ON_ERROR_STOP=1", "-A", "-t", "-f", "-"])
            server_env = {key: value for key, value in base_env.items() if not key.startswith("PG")}
            proc = subprocess.run(cmd, input=text, capture_output=True, text=True, env=server_env, cwd="/")
        elif who == "owner-sql":  # the owner in psql, with the page's URL and its ~/.pgpass
            proc = subprocess.run([psql, "postgresql://edc_admin@dbhost/edc", "-X", "-v", "ON_ERROR_STOP=1", "-f",
                                   str(script)], capture_output=True, text=True, env=env_of("owner"))
        else:
            proc = subprocess.run(["bash", "-e", "-o", "pipefail", str(script)], capture_output=True, text=True,
                                  env=env_of(who), cwd=homes[who])
        outputs.append(proc.stdout + proc.stderr)
        assert proc.returncode == 0, (step, who, text, proc.stdout, proc.stderr)
        if step == 3:
            assert "applied 0006" in proc.stdout and "created edc_station, edc_engineer, edc_owner" in proc.stdout
        if step == 5:
            assert "bench3: station Werkstatt Nord 3" in proc.stdout and "ines: station (none), person Ines Braun" \
                in proc.stdout
        if step == 6:  # the bootstrap right dropped, and the doc's check shows it
            assert "edc_admin|f|f|{edc_owner}" in proc.stdout, proc.stdout
        if step == 9:  # the station's test landed under its mapped name; its label was refused in one line
            assert "V-2040" in proc.stdout and "Werkstatt Nord 3" in proc.stdout, proc.stdout
            assert "'bench3' may not record teardown findings: ask the engineer's login" in proc.stderr
        if step == 10:
            assert "finding recorded" in proc.stdout and "ines" in proc.stdout
    # the owner can no longer make roles, nor grant itself the server's programs
    for sql in ("CREATE ROLE evil LOGIN", "GRANT pg_execute_server_program TO edc_admin"):
        refused = subprocess.run([psql, "postgresql://edc_admin@dbhost/edc", "-X", "-c", sql], capture_output=True,
                                 text=True, env=env_of("owner"))
        assert refused.returncode != 0 and ("permission denied" in refused.stderr
                                            or "must have admin option" in refused.stderr), (sql, refused.stderr)
    verify = subprocess.run(["bash", "-e", "-c", ". ~/.profile; edc-bench history --verify --station "
                                                 "'Werkstatt Nord 3'"], capture_output=True, text=True,
                            env=env_of("station"), cwd=homes["station"])
    assert verify.returncode == 0 and "the chain: holds" in verify.stderr, verify.stdout + verify.stderr
    for output in outputs:  # no step shows a password
        assert not any(password in output for password in PASSWORDS), output
