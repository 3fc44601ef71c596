"""The installed package's own files, for the tests that hold the program to never writing them (#52):
``from package_files import ...`` (``pythonpath = ["tests"]``, pyproject.toml)."""

from __future__ import annotations

import hashlib
import subprocess
import sys
from pathlib import Path

from helpers import REPO

from edc_bench.paths import package_folders


def package_digest(folders: tuple[Path, ...] | None = None) -> dict[str, str]:
    """SHA-256 of every file in the package's folders (default: the imported edc_bench's and firmware_proto's), by
    path; bytecode caches aside (Python may write those beside any module it imports)."""
    digest = {}
    for folder in folders or package_folders():
        for path in sorted(folder.rglob("*")):
            if path.is_file() and "__pycache__" not in path.parts:
                digest[str(path)] = hashlib.sha256(path.read_bytes()).hexdigest()
    return digest


def install_wheel(base: Path) -> Path:
    """The package as ``pip install .`` lays it out: a wheel built from this repository, installed with
    ``pip --target`` into ``base/site``.

    Run it with this interpreter and ``PYTHONPATH=base/site`` (its dependencies are this environment's). Built
    once for all test processes (``base`` shared, a lock file around the build); returns ``base/site``.
    """
    import fcntl

    site = base / "site"
    base.mkdir(parents=True, exist_ok=True)
    with open(base / "build.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if (site / "edc_bench").is_dir():
            return site
        _pip("wheel", "--no-deps", "--wheel-dir", str(base / "wheel"), str(REPO))
        wheel = next((base / "wheel").glob("edc_bench-*.whl"))
        _pip("install", "--no-deps", "--no-compile", "--target", str(site), str(wheel))
    return site


def _pip(*args: str) -> None:
    done = subprocess.run([sys.executable, "-m", "pip", *args, "--quiet"], capture_output=True, text=True,
                          timeout=1800)
    assert done.returncode == 0, f"pip {args[0]}: {done.stdout[-3000:]}{done.stderr[-3000:]}"
