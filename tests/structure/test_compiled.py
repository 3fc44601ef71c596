"""The wheel's compiled modules (hatch_build.py): there when installed from a wheel, never shadowing the source of an
editable install, and giving the same records as the source, to the bit (trace, frames and record.json)."""

from __future__ import annotations

import ast
import importlib
import importlib.machinery
import importlib.metadata
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

import edc_bench

ROOT = Path(__file__).resolve().parents[2]
RUNS_FROM_SOURCE = Path(edc_bench.__file__).resolve().parent == ROOT / "edc_bench"


def _compiled_list() -> tuple[str, ...]:
    """hatch_build.COMPILED, read without importing hatchling (a build dependency, not a test one)."""
    tree = ast.parse((ROOT / "hatch_build.py").read_text(encoding="utf-8"))
    for node in tree.body:
        if isinstance(node, ast.Assign) and any(getattr(t, "id", None) == "COMPILED" for t in node.targets):
            return tuple(ast.literal_eval(node.value))
    raise AssertionError("hatch_build.py has no COMPILED")


def _module_name(path: str) -> str:
    return path.removesuffix(".py").replace("/", ".")


def _is_compiled(name: str) -> bool:
    origin = importlib.import_module(name).__file__ or ""
    return origin.endswith(tuple(importlib.machinery.EXTENSION_SUFFIXES))


def _built_compiled() -> bool:
    """Whether the installed package should run compiled: a wheel built with the hook (a platform tag), not from
    source and not a wheel built with EDC_BENCH_PURE_PYTHON=1 (``py3-none-any``)."""
    if RUNS_FROM_SOURCE:
        return False
    wheel = importlib.metadata.distribution("edc-bench").read_text("WHEEL") or ""
    return "Tag: py3-none-any" not in wheel


def test_an_editable_install_runs_the_source_and_a_wheel_the_compiled_modules() -> None:
    compiled = {path: _is_compiled(_module_name(path)) for path in _compiled_list()}
    # all or none: a stale build in the tree would run instead of the source a developer edits, and a wheel that
    # lost a module would run it slower unseen
    assert set(compiled.values()) == {_built_compiled()}, compiled


# the same test, run by whichever edc_bench is first on the path; prints what must come out the same to the bit
_DIGEST = """
import hashlib, json, tempfile
from pathlib import Path
from edc_bench.bench import run_simulated_test
from edc_bench.config import load_variant
from edc_bench.records.record import write_record
# what differs between two runs of one test: when it ran, the wall clock's figures, the record's own hashes, and
# where the baseline file lies
WALL_CLOCK = {"timing": ("first_tick_unix_s", "stop_check_max_us", "cpu_steal_s"),
              "loop": ("first_tick_unix_s", "clock_origin_unix_s", "stop_check_max_s", "cpu_steal_s")}
out = {}
from edc_bench.testing.stalls import StallingClock
def stalls(clock):
    return StallingClock(clock, stall_s=0.005, every_s=1.0, first_s=2.5)
for case, variant, valve, adapter, wrapper in (("worn-usb-fs", "p-edc-default", "worn", "usb-fs", None),
                                               ("faulty-hard", "p-edc-hard", "faulty", None, None),
                                               ("new-host-stalls", "p-edc-default", "new", None, stalls)):
    result = run_simulated_test(load_variant(variant), valve, seed=3, adapter=adapter, clock_wrapper=wrapper)
    digest = hashlib.sha256()
    for name in sorted(result.trace):
        digest.update(name.encode() + result.trace[name].tobytes())
    frames = result.frames
    for column in (frames.t_s, frames.can_id, frames.dlc, frames.data, frames.rx, frames.flags):
        digest.update(column[:frames.count].tobytes())
    with tempfile.TemporaryDirectory() as folder:
        record = json.loads((write_record(result, Path(folder), figure=False) / "record.json").read_text())
    for section, keys in WALL_CLOCK.items():
        for key in keys:
            record[section].pop(key)
    for key in ("started_at", "test_id", "integrity", "files"):
        record.pop(key)
    record["baseline"].pop("path")  # the installed package's copy, or the repository's
    out[case] = {"trace_and_frames": digest.hexdigest(), "record_json": json.dumps(record, sort_keys=True)}
import edc_bench.engine.tick
out["tick_module"] = edc_bench.engine.tick.__file__
print(json.dumps(out, sort_keys=True))
"""


def _digest_in_process() -> dict:
    lines: list[str] = []
    namespace = {"print": lines.append}
    exec(_DIGEST, namespace)  # noqa: S102 - the test's own code, run here as in the subprocess
    return json.loads(lines[-1])


@pytest.mark.skipif(not _built_compiled(), reason="the installed package is not compiled (an editable install, or "
                                                   "a wheel built with EDC_BENCH_PURE_PYTHON=1): nothing to compare; "
                                                   "CI installs the compiled wheel")
def test_the_compiled_modules_give_the_records_of_the_source() -> None:
    assert _is_compiled("edc_bench.engine.tick")
    source = subprocess.run([sys.executable, "-c", _DIGEST], capture_output=True, text=True, check=True,
                            env={**os.environ, "PYTHONPATH": str(ROOT)}, cwd=ROOT)
    from_source = json.loads(source.stdout.strip().splitlines()[-1])
    compiled = _digest_in_process()
    assert from_source.pop("tick_module").endswith(".py") and not compiled.pop("tick_module").endswith(".py")
    assert json.loads(compiled["new-host-stalls"]["record_json"])["loop"]["gaps"] > 0  # the stalls cost ticks
    # a wrapped simulated clock is simulated time: once recorded as "real-time", with a false caution (#54)
    assert json.loads(compiled["new-host-stalls"]["record_json"])["clock"] == "simulated"
    assert from_source == compiled
