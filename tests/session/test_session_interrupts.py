"""`edc-bench session` sent Ctrl-C or SIGTERM (a `kill`, a shutdown) in a real terminal (tmux): exit 130, the
terminal given back, a started test ended safely with its record and history row kept, and the shift's summary
saying how it ended (#52). Inside the app Ctrl-C is a key, so the signal is sent to the process, as a service
manager or a shutdown sends it. Skips where tmux is not installed (.ci/run installs it)."""

from __future__ import annotations

import json
import os
import signal
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import can
import pytest
from tmux_terminal import NEEDS_TMUX, Terminal, set_up_station, terminal_env

from edc_bench.history.store import HistoryStore
from edc_bench.protocol import BENCH_CMD_ID, Mode, default_icd

pytestmark = [
    NEEDS_TMUX,
    pytest.mark.skipif(not Path("/proc/self").exists(), reason="reads the session's records through /proc's pids"),
]

SIGNALS = [pytest.param(signal.SIGINT, id="ctrl-c"), pytest.param(signal.SIGTERM, id="sigterm")]


class Session(Terminal):
    """``edc-bench session`` in a terminal of its own (140 x 45); its pid kept in ``session.pid``."""

    def __init__(self, cwd: Path) -> None:
        self.cwd, self.url = cwd, f"sqlite:///{cwd / 'h.sqlite'}"
        command = ["sh", "-c", 'echo $$ > session.pid; exec "$@"', "sh", sys.executable, "-m", "edc_bench", "session",
                   "--operator", "Anna", "--db", self.url]
        super().__init__(command, cwd, terminal_env({"EDC_BENCH_DATA_DIR": str(set_up_station(cwd / "data"))}))

    def send(self, sig: int) -> None:
        """Send ``sig`` to the session's process (the shell exec'd it: the pid it wrote is the app's)."""
        os.kill(int((self.cwd / "session.pid").read_text()), sig)


@pytest.fixture()
def session(tmp_path: Path) -> Iterator[Session]:
    started = Session(tmp_path)
    yield started
    started.close()


@pytest.mark.parametrize("sig", SIGNALS)
def test_a_signal_between_valves_ends_the_shift_with_130_and_its_summary(session: Session, tmp_path: Path,
                                                                        sig: int) -> None:
    session.wait_for("VALVE ID")
    session.send(sig)
    ended = session.wait_for("EXITED")
    assert "EXITED 130" in ended and "Traceback" not in ended
    assert "(ended by Ctrl-C or SIGTERM)" in ended and "edc-bench session: interrupted" in ended
    (summary,) = (tmp_path / "records").glob("shift-*.json")
    assert json.loads(summary.read_text())["ended_by"] == "interrupt"


@pytest.mark.parametrize("sig", SIGNALS)
def test_a_signal_mid_test_ends_it_safely_and_keeps_its_record_and_history_row(session: Session, tmp_path: Path,
                                                                               sig: int) -> None:
    session.wait_for("VALVE ID")
    session.keys("clearance=0.185", "Enter")  # a MARGINAL valve: its test runs to its full length
    session.wait_for("PUMP SERIAL")
    session.keys("PS-9", "Enter")
    session.wait_for("Mount the valve")
    session.keys("Enter")
    deadline = time.monotonic() + 90
    while not any(log.stat().st_size > 50 * 2 * 40 for log in (tmp_path / "records").glob("*/can.log")):
        assert time.monotonic() < deadline, session.screen()  # the test's ticks are in its CAN log: it runs
        time.sleep(0.005)
    finished_first = any((tmp_path / "records").glob("*/record.json"))
    session.send(sig)
    ended = session.wait_for("EXITED")
    (folder,) = [path for path in (tmp_path / "records").iterdir() if path.is_dir()]  # no retest started
    doc = json.loads((folder / "record.json").read_text())
    if finished_first or doc["loop"]["abort_reason"] != "interrupted by the operator":
        pytest.skip(f"the simulated test ended before the signal came ({doc['stop']}): this machine was too fast "
                    "or too busy to hit it")
    assert "EXITED 130" in ended and "Traceback" not in ended, ended
    assert "valves: 1 (1 INVALID); tests: 1" in ended
    assert doc["verdict"] == "INVALID"
    if not doc["loop"]["safe_confirmed"]:  # the rig left safe: SAFE confirmed, or never driven
        icd = default_icd()
        assert not any(f.arbitration_id == BENCH_CMD_ID and icd.bench_cmd.decode(bytes(f.data))[2] == Mode.RUN
                       for f in can.LogReader(str(folder / "can.log")))
    with HistoryStore(session.url) as store:
        (row,) = store.list()
    assert row.valve_id == "clearance=0.185" and row.verdict == "INVALID"
