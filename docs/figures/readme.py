"""README.md's figures: the test suite's size and how long its default run takes."""

from __future__ import annotations

import re
import subprocess
import sys
import time
from pathlib import Path

from figures.common import measurement, stored, when_and_where, wrap

ROOT = Path(__file__).resolve().parents[2]


def _collected(marker: str) -> int:
    """How many tests ``pytest -m MARKER`` selects (collected only, nothing run)."""
    done = subprocess.run([sys.executable, "-m", "pytest", "--collect-only", "-q", "-p", "no:cacheprovider",
                           "-n", "0", "-m", marker], cwd=ROOT, capture_output=True, text=True, check=False)
    found = re.search(r"(\d+)(?:/\d+)? tests? collected", done.stdout)
    if found is None:
        raise RuntimeError(f"pytest collected nothing for -m {marker!r}:\n{done.stdout[-2000:]}{done.stderr[-2000:]}")
    return int(found.group(1))


@measurement("readme-suite-minutes", minutes=4, timing=True)
def suite_minutes() -> dict[str, float]:
    """Wall time of the README's test command (the default suite, two workers) on this machine.

    The suite includes the check of these pages, which fails while this very figure is being measured (its
    stored result is what is missing or changing); any other failure means the time is not a figure.
    """
    start_s = time.perf_counter()
    done = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-rf"], cwd=ROOT,
                          capture_output=True, text=True, check=False)
    minutes = round((time.perf_counter() - start_s) / 60.0, 1)
    failed = [line for line in done.stdout.splitlines() if line.startswith("FAILED ")]
    if done.returncode not in (0, 1) or any("tests/docs/test_figures.py" not in line for line in failed):
        raise RuntimeError(f"the default suite failed; its time is not a figure:\n{done.stdout[-3000:]}")
    return {"default_suite_min": minutes}


def test_suite_paragraph() -> str:
    """The paragraph after the quick start: what the README's second command runs, and how long it takes."""
    minutes = stored("readme-suite-minutes")["default_suite_min"]
    slow = _collected("slow")
    realtime = _collected("realtime and not slow")
    return wrap(f"The second runs the default suite on two workers (pytest-xdist; `-n 0` for one): "
            f"{minutes:.1f} minutes ({when_and_where('readme-suite-minutes')}; "
            f"`python docs/regenerate.py --measure readme-suite-minutes` measures it again). Nothing it judges "
            f"depends on how busy the PC is (docs/testing.md). It leaves out the {slow} slow tests (the paper's "
            f"experiment, model rebuilds, population runs, the docs' measurements, the benchmark, long "
            f"real-time runs) and {realtime} short real-time ones (a rig process on loopback in wall-clock time; "
            f"the two-worker summary counts neither): run them with `pytest -m 'slow or realtime' -n 0`, "
            f"one at a time, since the real-time ones want the machine to themselves. CI runs them all, the slow "
            f"tests in simulated time on two workers and the real-time ones and the benchmark alone "
            f"(`.ci/run`). Both commands may share one virtual environment (re-running `venv` on it keeps what "
            f"is installed). The history and caches go under your home folder (\"Where files go\" below).")


@measurement("readme-sizes", minutes=1)
def sizes() -> dict[str, float]:
    """What an install and a test take on disk: this virtual environment (it must hold the test extras, as README
    command 2 installs them) and the record folder of one default test on the simulated rig."""
    import importlib.util
    import tempfile

    missing = [m for m in ("pytest", "sklearn", "skl2onnx", "selenium") if importlib.util.find_spec(m) is None]
    if missing:
        raise RuntimeError(f"measure the sizes in a venv with the test extras (pip install '.[test]'): {missing}")

    def size_mb(folder: Path) -> float:
        return sum(f.stat().st_size for f in folder.rglob("*") if f.is_file() and not f.is_symlink()) / 1e6

    with tempfile.TemporaryDirectory() as out:
        subprocess.run([sys.executable, "-m", "edc_bench", "test", "--no-history", "--plain", "--out", out],
                       cwd=out, capture_output=True, text=True, check=True)
        (record,) = Path(out).iterdir()
        record_mb = size_mb(record)
    return {"venv_gb": round(size_mb(Path(sys.prefix)) / 1e3, 1), "record_mb": round(record_mb, 1)}


def sizes_sentence() -> str:
    """README's prerequisites: the disk an install with the test extras takes and a test's record."""
    measured = stored("readme-sizes")
    return (f"about {measured['venv_gb']:.1f} GB for the virtual environment with the test extras "
            f"(`python docs/regenerate.py --measure readme-sizes`), and {measured['record_mb']:.1f} MB for each "
            f"test's record (`record.json`, `trace.mf4`, `can.log`, `report.png`)")
