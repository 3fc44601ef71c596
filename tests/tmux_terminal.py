"""A real terminal for the tests that type at the app as a technician would: a tmux session of its own, its screen
read back with capture-pane (``from tmux_terminal import Terminal``; ``pythonpath = ["tests"]``, pyproject.toml)."""

from __future__ import annotations

import os
import shlex
import shutil
import subprocess
import time
from collections.abc import Mapping
from pathlib import Path

import pytest

#: for a module's ``pytestmark``: tmux is an apt package (.ci/run installs it)
NEEDS_TMUX = pytest.mark.skipif(shutil.which("tmux") is None, reason="tmux is not installed (apt-get install tmux)")


def terminal_env(extra: Mapping[str, str]) -> dict[str, str]:
    """This process's environment for the app, with ``extra``: without COLUMNS and LINES (which pytest's workers may
    carry, and which would override the terminal's size for Textual), TERM an xterm's."""
    env = {key: value for key, value in os.environ.items() if key not in ("COLUMNS", "LINES")}
    env.update(TERM="xterm-256color", **extra)
    return env


def set_up_station(data_dir: Path) -> Path:
    """A station data folder whose settings name the workshop already (``[station] shop``): the session does not
    ask for it (a test of that question starts from an empty folder); the folder."""
    data_dir.mkdir(parents=True, exist_ok=True)
    (data_dir / "station.toml").write_text('[station]\nshop = "Diesel Müller GmbH"\n', encoding="utf-8")
    return data_dir


class Terminal:
    """A tmux session of its own, ``columns`` x ``rows``, running one command; ``EXITED <code>`` shown when it ends.

    Parameters
    ----------
    command : list of str
        What runs in it (quoted for its shell).
    cwd : pathlib.Path
        Where; the tmux server's socket is made there too.
    env : mapping
        Its environment (:func:`terminal_env`).
    """

    def __init__(self, command: list[str], cwd: Path, env: Mapping[str, str], columns: int = 140,
                 rows: int = 45) -> None:
        self.name = f"edc-{os.urandom(4).hex()}"
        self.socket = str(cwd / "tmux.sock")
        shell = " ".join(shlex.quote(part) for part in command) + "; echo EXITED $?; sleep 600"
        size = ["-x", str(columns), "-y", str(rows)]
        subprocess.run(["tmux", "-S", self.socket, "new-session", "-d", "-s", self.name, *size, "-c", str(cwd), shell],
                       check=True, env=dict(env))
        # the size stays as asked whatever clients or defaults this tmux has (no client ever attaches)
        subprocess.run(["tmux", "-S", self.socket, "set-option", "-t", self.name, "window-size", "manual"],
                       check=False, capture_output=True)
        subprocess.run(["tmux", "-S", self.socket, "resize-window", "-t", self.name, *size],
                       check=False, capture_output=True)

    def keys(self, *keys: str) -> None:
        """Type ``keys`` (tmux's names: ``Enter``, ``C-q``; anything else as text)."""
        subprocess.run(["tmux", "-S", self.socket, "send-keys", "-t", self.name, *keys], check=True)

    def screen(self) -> str:
        """What the terminal shows now."""
        return subprocess.run(["tmux", "-S", self.socket, "capture-pane", "-p", "-t", self.name],
                              capture_output=True, text=True, check=True).stdout

    def wait_for(self, text: str, timeout_s: float = 90.0) -> str:
        """The screen once it shows ``text`` (waits on the app, not on a clock: a slow machine only waits longer)."""
        deadline = time.monotonic() + timeout_s
        while text not in (screen := self.screen()):
            if time.monotonic() > deadline:
                raise AssertionError(f"the screen never showed {text!r}; it shows:\n{screen}")
            time.sleep(0.1)
        return screen

    def close(self) -> None:
        """End the terminal and whatever still runs in it."""
        subprocess.run(["tmux", "-S", self.socket, "kill-server"], check=False, capture_output=True)
