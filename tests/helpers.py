"""Plain helpers shared by the test modules: ``from helpers import ...`` (``pythonpath = ["tests"]``, pyproject.toml)."""

from __future__ import annotations

import subprocess
import sys
from collections.abc import Mapping
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent  # the repository's root (configs/, docs/, ...)


def edc_bench(*args: str, cwd: Path | None = None, timeout: float = 600,
              env: Mapping[str, str] | None = None) -> subprocess.CompletedProcess:
    """Run ``edc-bench ARGS`` (``python -m edc_bench``) in a subprocess; output captured as text."""
    return subprocess.run([sys.executable, "-m", "edc_bench", *args], capture_output=True, text=True, cwd=cwd,
                          timeout=timeout, env=env)
