"""``edc-bench web`` as a shop starts it: it binds its own socket before it prints the URL (so a port it cannot
serve on is one line, tests/cli/test_plain_install.py), then serves there until SIGTERM. Nothing is timed: the
first line is read and one page fetched, with hang guards far above what they need."""

from __future__ import annotations

import signal
import socket
import subprocess
import sys
from pathlib import Path

import httpx2 as httpx

from edc_bench.history.store import HistoryStore


def test_the_web_command_serves_on_the_socket_it_bound_and_stops_on_sigterm(tmp_path: Path) -> None:
    url = f"sqlite:///{tmp_path / 'h.sqlite'}"
    HistoryStore(url).close()
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    web = subprocess.Popen([sys.executable, "-m", "edc_bench", "web", "--port", str(port), "--db", url,
                            "--records", str(tmp_path)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert web.stdout is not None
        first = web.stdout.readline()
        assert f"on http://127.0.0.1:{port}/" in first and "access token:" in first, first
        # the socket is listening once the URL is printed: the page answers (a redirect to sign in)
        page = httpx.get(f"http://127.0.0.1:{port}/", timeout=60, follow_redirects=False)
        assert page.status_code in (200, 303), page.status_code
    finally:
        web.send_signal(signal.SIGTERM)
        _, err = web.communicate(timeout=60)
    assert web.returncode in (0, 130), err
    assert "Traceback" not in err, err
