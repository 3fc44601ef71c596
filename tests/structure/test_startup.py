"""What 'edc-bench test' imports before its first tick: nothing it needs only after the test.

The start of a test is what a technician waits for at every valve. Each
module named here was once imported before the first tick, and made the
wait measurably longer (python-can's MF4 support with asammdf and pandas,
the history's database layer, SciPy; docs/performance.md has the figures);
this test fails when one comes back.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

#: Imported after the test or never by 'edc-bench test' on the simulated rig (and on a bus: the same path).
NOT_BEFORE_THE_FIRST_TICK = ("asammdf", "pandas", "sqlalchemy", "scipy", "matplotlib", "control",
                             "edc_bench.perf.suite", "numba")

_PROBE = """
import json, sys
from edc_bench.runtime.loop import BenchLoop

run_ticks = BenchLoop._run_ticks
seen = []

def first_tick(self):
    if not seen:
        seen.append(sorted(sys.modules))
    return run_ticks(self)

BenchLoop._run_ticks = first_tick
from edc_bench.cli import main
code = main(sys.argv[1:])
print("MODULES " + json.dumps(seen[0]), file=sys.stderr)
"""


def test_the_test_command_reaches_its_first_tick_without_what_it_needs_only_later(tmp_path: Path) -> None:
    env = {**os.environ, "EDC_BENCH_CACHE_DIR": str(tmp_path / "cache"), "EDC_BENCH_HISTORY_URL": f"sqlite:///{tmp_path}/h.db"}
    for _ in range(2):  # the second run finds the gain check cached, as a station's every test after its first
        proc = subprocess.run([sys.executable, "-c", _PROBE, "test", "--json", "--no-figure", "--duration-s", "8",
                               "--out", str(tmp_path / "rec")], capture_output=True, text=True, env=env, timeout=120)
    line = next(x for x in proc.stderr.splitlines() if x.startswith("MODULES "))
    modules = set(json.loads(line[len("MODULES "):]))
    early = [name for name in NOT_BEFORE_THE_FIRST_TICK if name in modules]
    assert early == [], f"imported before the first tick: {early}"
    assert json.loads(proc.stdout)["verdict"], proc.stdout  # and the test ran to its verdict, record written
    assert {"can", "numpy", "onnxruntime"} <= modules  # the probe saw the loop's start, not an empty process
