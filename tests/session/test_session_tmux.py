"""`edc-bench session` in a real terminal (tmux), typed at as a technician would: the screen read back with
capture-pane. Skips where tmux is not installed (.ci/run installs it)."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import time
import uuid
from pathlib import Path

import pytest

pytestmark = pytest.mark.skipif(shutil.which("tmux") is None, reason="tmux is not installed (apt-get install tmux)")


class Terminal:
    """A tmux session of its own, 140 x 45, running one command."""

    def __init__(self, command: list[str], cwd: Path, env: dict[str, str]) -> None:
        self.name = f"edc-{uuid.uuid4().hex[:8]}"
        self.socket = str(cwd / "tmux.sock")
        shell = " ".join(_quote(part) for part in command) + "; echo EXITED $?; sleep 600"
        subprocess.run(["tmux", "-S", self.socket, "new-session", "-d", "-s", self.name, "-x", "140", "-y", "45",
                        "-c", str(cwd), shell], check=True, env=env)
        # the size stays 140 x 45 whatever clients or defaults this tmux has (no client ever attaches)
        subprocess.run(["tmux", "-S", self.socket, "set-option", "-t", self.name, "window-size", "manual"],
                       check=False, capture_output=True)
        subprocess.run(["tmux", "-S", self.socket, "resize-window", "-t", self.name, "-x", "140", "-y", "45"],
                       check=False, capture_output=True)

    def keys(self, *keys: str) -> None:
        subprocess.run(["tmux", "-S", self.socket, "send-keys", "-t", self.name, *keys], check=True)

    def screen(self) -> str:
        return subprocess.run(["tmux", "-S", self.socket, "capture-pane", "-p", "-t", self.name],
                              capture_output=True, text=True, check=True).stdout

    def wait_for(self, text: str, timeout_s: float = 90.0) -> str:
        """The screen once it shows ``text`` (waits on the app, not on a clock: a slow machine only waits longer)."""
        deadline = time.monotonic() + timeout_s
        while True:
            screen = self.screen()
            if text in screen:
                return screen
            if time.monotonic() > deadline:
                raise AssertionError(f"the screen never showed {text!r}; it shows:\n{screen}")
            time.sleep(0.2)

    def close(self) -> None:
        subprocess.run(["tmux", "-S", self.socket, "kill-server"], check=False, capture_output=True)


def _quote(text: str) -> str:
    import shlex

    return shlex.quote(text)


@pytest.mark.slow  # the default suite's 5 minutes; CI's slow pass runs it
def test_a_technician_works_a_short_shift_in_a_real_terminal(tmp_path: Path) -> None:
    # COLUMNS and LINES (which pytest's workers may carry) would override the terminal's size for Textual
    env = {key: value for key, value in os.environ.items() if key not in ("COLUMNS", "LINES")}
    env.update(EDC_BENCH_DATA_DIR=str(tmp_path / "data"), TERM="xterm-256color")
    term = Terminal([sys.executable, "-m", "edc_bench", "session", "--db", f"sqlite:///{tmp_path / 'h.sqlite'}"],
                    tmp_path, env)
    try:
        term.wait_for("Type your NAME")
        term.keys("Anna", "Enter")
        term.wait_for("operator Anna")
        term.keys("clearance=0.185", "Enter")
        term.wait_for("PUMP SERIAL")
        term.keys("PS-4471", "Enter")
        term.wait_for("Mount the valve")
        term.keys("Enter")
        decided = term.wait_for("NEAR THE LIMIT TWICE: REPLACE THE VALVE")
        assert "FAIL  (MARGINAL, retest MARGINAL)" in decided
        term.keys("new", "Enter")
        term.wait_for("PUMP SERIAL")
        term.keys("PS-4472", "Enter")
        term.wait_for("Mount the valve")
        term.keys("Enter")
        passed = term.wait_for("REUSABLE: REFIT THE VALVE")
        assert "valves 2, tests 3" in passed
        term.keys("C-q")
        ended = term.wait_for("EXITED")
    finally:
        term.close()
    assert "EXITED 0" in ended
    assert "valves: 2 (1 PASS, 1 FAIL); tests: 3; retests: 1" in ended
    assert "shift summary: records/shift-" in ended
