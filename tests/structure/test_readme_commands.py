"""README's two commands and its tour run verbatim, as a newcomer types them, in a fresh virtual environment made
from a copy of the repository (slow: it installs the package and its dependencies)."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from helpers import REPO

pytestmark = pytest.mark.slow

README = (REPO / "README.md").read_text(encoding="utf-8")


def _blocks() -> list[list[str]]:
    """README's ``sh`` blocks, each as its command lines (comments and blank lines left out)."""
    return [[line for line in block.splitlines() if line.strip() and not line.lstrip().startswith("#")]
            for block in re.findall(r"```sh\n(.*?)```", README, re.DOTALL)]


def _tracked_copy(target: Path) -> Path:
    """The repository's tracked files (and their changes not yet committed), as a clone would have them."""
    names = subprocess.run(["git", "ls-files", "-z"], cwd=REPO, capture_output=True, check=True).stdout.split(b"\0")
    for name in filter(None, names):
        source = REPO / name.decode()
        if source.is_file():
            (target / name.decode()).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(source, target / name.decode())
    return target


def test_the_readme_has_two_commands_and_a_tour() -> None:
    quick, tour = _blocks()[:2]
    assert len(quick) == 2 and all(line.startswith("python3.11 -m venv .venv && . .venv/bin/activate") for line in quick)
    assert quick[0].endswith("pip install . && edc-bench test")
    # command 2 is what .ci/run runs (the suite cannot run itself here)
    assert quick[1].endswith('pip install ".[test]" && pytest')
    ci = (REPO / ".ci" / "run").read_text(encoding="utf-8")
    assert 'pip install ".[test]"\n' in ci and "\npytest || status=$?\n" in ci
    assert all(line.startswith("edc-bench ") for line in tour)


def test_command_1_and_the_tour_run_verbatim_in_a_fresh_venv(tmp_path: Path) -> None:
    quick, tour = _blocks()[:2]
    clone = _tracked_copy(tmp_path / "edc-bench")
    python = shutil.which("python3.11") or sys.executable  # README: "python3.12 or python3.13 ... with another version"
    env = {k: v for k, v in os.environ.items() if not k.startswith(("EDC_BENCH_", "VIRTUAL_ENV", "PYTHON"))}
    env.update(HOME=str(tmp_path / "home"), EDC_BENCH_DATA_DIR=str(tmp_path / "data"),
               XDG_CACHE_HOME=str(tmp_path / "cache"), PIP_CACHE_DIR=os.environ.get("PIP_CACHE_DIR",
                                                                                   str(Path.home() / ".cache/pip")))
    (tmp_path / "home").mkdir()

    def run(command: str, timeout: float = 600) -> subprocess.CompletedProcess[str]:
        line = command.replace("python3.11", python, 1)
        return subprocess.run(["bash", "-c", line], cwd=clone, env=env, capture_output=True, text=True,
                              timeout=timeout)

    first = run(quick[0], timeout=1800)
    assert first.returncode == 0, first.stdout[-2000:] + first.stderr[-3000:]
    assert "verdict: PASS" in first.stdout or "PASS" in first.stdout
    activate = ". .venv/bin/activate && "
    fail_folder = None
    for line in tour:
        command = line.split("  #")[0].strip()
        if "<the FAIL test's folder>" in command or "<a test's folder>" in command:
            assert fail_folder is not None, "the tour reports on a test before one failed"
            command = re.sub(r"records/<[^>]+>", f"records/{fail_folder}", command)
        expected = re.search(r"\(exit (\d+)\)", line)
        done = run(activate + command)
        said = f"{command}: exit {done.returncode}\n{done.stdout[-1500:]}{done.stderr[-1500:]}"
        if expected:
            assert done.returncode == int(expected.group(1)), said
        elif command.startswith("edc-bench check-station"):
            assert done.returncode in (0, 14), said  # GO, or NO-GO on a busy machine: both are its answer
        elif command.startswith("edc-bench test") and "INVALID" in line:
            assert done.returncode == 12, said
        else:
            assert done.returncode == 0, said
        assert "Traceback" not in done.stderr, said
        if command.startswith("edc-bench test --valve worn"):
            (folder,) = [p.name for p in (clone / "records").iterdir() if "V-2040" in p.name]
            fail_folder = folder
    # the plain install (no extras): a command that needs one says which in one line, before any work; a port
    # that cannot be served is one line, not a traceback
    paper = run(activate + "edc-bench paper", timeout=120)
    assert paper.returncode == 2 and "needs the 'train' extra" in paper.stderr, paper.stderr[-2000:]
    assert paper.stderr.count("\n") == 1
    web = run(activate + "edc-bench web --port 99999", timeout=120)
    assert web.returncode == 2 and "give one from 1 to 65535" in web.stderr and web.stdout == "", web.stderr
