"""A shift's load (slow): 1,500 simulated tests back to back in one session process, driven through the app as a
technician would (scan, scan, Enter), with memory and open files measured as it goes.

The report is drawn for every tenth valve (each draw is half the cost of a test; 150 draws still show a leak of
matplotlib's). EDC_BENCH_SOAK_TESTS sets another count (at least 300): CI runs 300 (.ci/run), since 1,500 take
about 55 minutes at 2.1 s a test through the app (docs/station.md has a full run's figures). The full run found 10
tests missing from the history once: valves beyond the classifier's distance scan, whose records could not be read.
"""

from __future__ import annotations

import asyncio
import os
import shutil
import sys
from pathlib import Path

import numpy as np
import pytest

from edc_bench.session.build import make_app
from edc_bench.history.store import HistoryStore
from edc_bench.records.reader import load_record
from edc_bench.session.runner import RigChoice

@pytest.fixture(autouse=True)
def _station_data(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A station data folder of this test's own (the operator is remembered there)."""
    monkeypatch.setenv("EDC_BENCH_DATA_DIR", str(tmp_path / "station-data"))


TESTS = int(os.environ.get("EDC_BENCH_SOAK_TESTS", "1500"))
WARM_UP_TESTS = min(200, TESTS // 5)  # caches, the classifier's session, matplotlib's fonts: filled by then
SAMPLE_EVERY = 10  # tests: often enough that each half's floor misses the transients of a report just drawn
# A leak is looked for twice, from the soak's first half to its second (after the warm-up):
# - Python's allocated blocks (live objects), whose floor may rise this much a test: exact, and blind to how the
#   allocators keep freed memory. Measured: about 90 a test (the shift's own list of valves among them); a test that
#   leaked its trace or its frames (tens of thousands of objects) would pass it at once.
MAX_BLOCKS_PER_TEST = 250
# - resident memory, for what C libraries hold (numpy's buffers, matplotlib's, onnxruntime's): its floor may rise
#   this much. glibc keeps freed memory in per-thread arenas (each test runs in a new worker thread), and a half's
#   floor can sit on such a plateau for a hundred tests: 300-test runs measured +0.0, +27 and +34 MB with no leak
#   in the blocks. A test that leaked its trace (a few MB) would pass 60 MB within tens of tests.
MAX_GROWTH_MB = 60.0


def _rss_mb() -> float:
    """Resident memory of what is alive: after a collection, with the C allocator's free pages handed back (glibc
    keeps freed memory in per-thread arenas, and each test runs in a new worker thread)."""
    import ctypes
    import gc

    gc.collect()
    try:
        ctypes.CDLL("libc.so.6").malloc_trim(0)
    except (OSError, AttributeError):  # not glibc: RSS as it is
        pass
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024
    raise AssertionError("no VmRSS in /proc/self/status")


def _python_blocks() -> int:
    """Memory blocks Python's allocator holds for live objects (after a collection): unlike resident memory, not
    raised by arenas a freed object leaves half-used, so a leak of Python objects shows here at once."""
    import gc

    gc.collect()
    return sys.getallocatedblocks()


def _open_files() -> int:
    return len(os.listdir("/proc/self/fd"))


@pytest.mark.slow
@pytest.mark.skipif(not Path("/proc/self/status").exists(), reason="measures memory and files through /proc (Linux)")
def test_a_shift_of_1500_tests_in_one_session_process(tmp_path: Path) -> None:
    db = f"sqlite:///{tmp_path / 'history.sqlite'}"
    out = tmp_path / "records"
    samples: list[tuple[int, float, int, int]] = []  # (tests, RSS MB, open files, Python's blocks)

    async def shift():
        app = make_app(None, RigChoice(), out, db, "soak-bench", "Soak Tester")
        async with app.run_test(size=(140, 45)) as pilot:
            await pilot.pause()
            valve = 0
            while app.shift.tests < TESTS:
                app.runner.report = valve % 10 == 0
                entry = app.query_one("#entry")
                for line in (f"V-{valve:05d}", f"PS-{valve:05d}", ""):  # as a scanner types: a line, then Enter
                    entry.value = line
                    await pilot.press("enter")
                await app.workers.wait_for_complete()
                await pilot.pause()
                valve += 1
                if app.shift.tests // SAMPLE_EVERY > len(samples):
                    samples.append((app.shift.tests, _rss_mb(), _open_files(), _python_blocks()))
            await pilot.press("ctrl+q", "ctrl+q")
            await pilot.pause()
        return app

    app = asyncio.run(shift())
    tests, rss, files, blocks = (np.array(column) for column in zip(*samples, strict=True))
    after = tests >= WARM_UP_TESTS
    middle = tests[after][0] + (tests[-1] - tests[after][0]) / 2
    # the floor: a sample taken just after a report was drawn holds matplotlib's transient buffers (+85 MB seen)
    early_floor, late_floor = float(rss[after & (tests <= middle)].min()), float(rss[tests > middle].min())
    early_blocks, late_blocks = int(blocks[after & (tests <= middle)].min()), int(blocks[tests > middle].min())
    print("samples (tests, MB, files, blocks):", [(int(t), round(float(m), 1), int(f), int(b))
                                                  for t, m, f, b in samples])
    print(f"Python's blocks: floor {early_blocks} in the first half, {late_blocks} in the second "
          f"({late_blocks - early_blocks:+d}, {(late_blocks - early_blocks) / (tests[-1] - middle):+.1f} a test)")
    print(f"{app.shift.tests} tests of {len(app.shift.valves)} valves ({app.shift.retests} retests): resident "
          f"memory {rss[0]:.0f} MB at {tests[0]} tests; its floor {early_floor:.1f} MB from {tests[after][0]} to "
          f"{middle:.0f} tests, {late_floor:.1f} MB from there to {tests[-1]} ({late_floor - early_floor:+.1f} MB), "
          f"highest {rss.max():.0f} MB; open files {files.min()}-{files.max()} (after the warm-up "
          f"{files[after].min()}-{files[after].max()})")
    assert (late_blocks - early_blocks) / (tests[-1] - middle) <= MAX_BLOCKS_PER_TEST
    assert late_floor - early_floor <= MAX_GROWTH_MB
    assert files[after].max() - files[after].min() <= 2  # a leaked file per test would show 10 per sample
    # the history whole, every record readable, and the shift summary as a file
    with HistoryStore(db) as store:
        rows = store.list()
    assert len(rows) == app.shift.tests
    assert {r.operator for r in rows} == {"Soak Tester"}
    folders = [Path(r.record_dir) for r in rows]
    assert len(set(folders)) == len(folders)
    for folder in folders:
        load_record(folder)  # checks the record's integrity manifest too
    assert sum(1 for r in rows if r.decision) == app.shift.retests
    assert f"tests: {app.shift.tests}; retests: {app.shift.retests}" in app.summary_file.read_text()
    shutil.rmtree(out, ignore_errors=True)  # 2 MB a test: leave no 3 GB behind in pytest's temp folders
