"""Population throughput of the batch path, and start-up times of the command line."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np


@dataclass(frozen=True)
class BatchThroughput:
    """Batch-path tests per minute: one process early-stopped, a pool of ``workers``, one process full length."""

    valves: int
    per_minute_one_process: float
    per_minute_pool: float
    workers: int
    per_minute_full_length: float
    median_stop_s: float
    mean_stop_s: float
    full_length_s: float


@dataclass(frozen=True)
class StartTimes:
    """Wall times of a command (s): the best and the median of ``repeats``, and the first (cold) where it differs."""

    best_s: float
    median_s: float
    repeats: int
    cold_s: float | None = None


def batch(variant_name: str | None, valves: int, workers: int) -> BatchThroughput:
    """Valve tests per minute in the batch path, each test stopped where the bench's early stop ends it (the
    model the variant's valves are judged by, and the packaged baseline): one process, and ``workers`` processes
    with ``valves`` each; and one process running every test its full length (as training data are made), for
    comparison. The one-process figures are timed after a batch of two, which loads (on a new station, compiles)
    the batch path's compiled kernels; the pool's figure includes what its workers pay to start."""
    from edc_bench.config import load_variant
    from edc_bench.learning.dataset import run_population
    from edc_bench.population.batch import run_batch
    from edc_bench.population.batch_stop import BatchStopRule
    from edc_bench.population.valves import draw_population

    variant = load_variant(variant_name)
    population = draw_population(variant, valves, 7)
    seeds = list(range(valves))
    rule = BatchStopRule.shipped(variant)
    # once per process, not per test: numba's import and the compiled kernels (compiled on a station's first batch)
    run_batch(variant, population[:2], seeds[:2], stop=rule)
    t0 = time.perf_counter()
    stopped = run_batch(variant, population, seeds, stop=rule)
    one = time.perf_counter() - t0
    t0 = time.perf_counter()
    run_population(variant, population + population, seeds + [s + valves for s in seeds], workers, early_stop=True,
                   chunk=valves)
    many = time.perf_counter() - t0
    t0 = time.perf_counter()
    run_batch(variant, population, seeds)
    full = time.perf_counter() - t0
    return BatchThroughput(valves, valves / one * 60.0, 2 * valves / many * 60.0, workers, valves / full * 60.0,
                           float(np.median(stopped.stop.time_s)), float(stopped.stop.time_s.mean()),
                           float(variant.excitation.duration_s))


def _command(*args: str) -> list[str]:
    return [sys.executable, "-m", "edc_bench", *args]


def help_time(repeats: int) -> StartTimes:
    """Wall time of ``edc-bench --help`` (process start to exit), best and median."""
    walls = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        subprocess.run(_command("--help"), capture_output=True, check=True)
        walls.append(time.perf_counter() - t0)
    return StartTimes(min(walls), float(np.median(walls)), repeats)


def bare_python_time(repeats: int) -> float:
    """Best wall time of ``python -c pass``: the interpreter's own start-up, for reference."""
    walls = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        subprocess.run([sys.executable, "-c", "pass"], check=True)
        walls.append(time.perf_counter() - t0)
    return min(walls)


def time_to_first_tick(repeats: int) -> StartTimes:
    """Time from launching ``edc-bench test`` (simulated rig) to its first tick: cold, then best and median warm.

    The test reports the wall-clock time of its first tick in its JSON
    summary (``timing.first_tick_unix_s``); the rest of the run is not timed.
    The first run has an empty cache, as on a new station (the gain check
    imports python-control); the others find the gain check's result cached.
    """
    walls = []
    with tempfile.TemporaryDirectory() as out:
        env = {**os.environ, "EDC_BENCH_CACHE_DIR": str(Path(out) / "cache")}
        for _ in range(repeats + 1):
            t0 = time.time()
            proc = subprocess.run(_command("test", "--json", "--no-figure", "--duration-s", "8", "--out", out),
                                  capture_output=True, text=True, env=env)
            try:
                first = json.loads(proc.stdout)["timing"]["first_tick_unix_s"]
            except (ValueError, KeyError, TypeError):
                raise RuntimeError(f"edc-bench test gave no first-tick time: {proc.stderr.strip()[-500:]}") from None
            walls.append(first - t0)
    warm = walls[1:]
    return StartTimes(min(warm), float(np.median(warm)), repeats, cold_s=walls[0])
