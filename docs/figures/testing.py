"""docs/testing.md's list: every module of the default suite that reads a clock, and why no machine can fail it
(from tests/machine_time.py, which the structure test holds to the suite)."""

from __future__ import annotations

import importlib.util
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def _registry():  # noqa: ANN202 - the tests' module, loaded by path (tests/ is not a package)
    spec = importlib.util.spec_from_file_location("machine_time", ROOT / "tests" / "machine_time.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def clock_table() -> str:
    """The Markdown table of tests/machine_time.py's MODULES, then the modules whose clocks are in slow tests."""
    registry = _registry()
    rows = ["| module | kind | why no machine can fail it |", "| --- | --- | --- |"]
    rows += [f"| `{name}` | {', '.join(str(k) for k in kinds)} | {why} |"
             for name, (kinds, why) in sorted(registry.MODULES.items())]
    rows += ["", "Modules whose clock reads are all in slow or real-time tests (not in the default suite):", ""]
    rows += [f"- `{name}`: {why}" for name, why in sorted(registry.ONLY_IN_SLOW_TESTS.items())]
    return "\n".join(rows)
