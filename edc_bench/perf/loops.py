"""Whole loops: the simulated bench test, and the real-time loop beside a bare one.

The real-time loop runs the bench test against the rig process over
slcan/TCP. Beside it, in the same run and for as long, a bare loop only
waits for its deadlines with the same clock: its lateness is what this
machine allows at all (the floor). A separate process samples the
hypervisor's steal from /proc/stat every 20 ms, so overruns can be told
apart: those in a window where the machine lost its CPU, and the others.
"""

from __future__ import annotations

import gc
import subprocess
import sys
import time
from dataclasses import dataclass

import numpy as np

from edc_bench.config import Variant, with_changes
from edc_bench.perf.figures import percentiles
from edc_bench.runtime.clock import RealTimeClock, cpu_steal_s

#: A window is "stolen" when the hypervisor took at least this much CPU in it.
STEAL_WINDOW_MIN_S = 0.002


def with_timing(variant: Variant, period_s: float | None = None, duration_s: float | None = None) -> Variant:
    """The variant with another tick period or test duration (validated again).

    A duration too short for the convergence window shrinks the window: a
    timing benchmark does not judge the identification.
    """
    changes: dict[str, dict[str, float]] = {"controller": {}, "excitation": {}, "acceptance": {}}
    if period_s is not None:
        changes["controller"]["period_s"] = period_s
    if duration_s is not None:
        changes["excitation"]["duration_s"] = duration_s
        room_s = duration_s - variant.excitation.move_s - variant.excitation.fade_s
        if room_s <= variant.acceptance.convergence_window_s:
            changes["acceptance"]["convergence_window_s"] = max(room_s / 2.0, 1e-3)
    return with_changes(variant, changes, "a benchmark's timing")


@dataclass(frozen=True)
class SimulatedTiming:
    """Wall times of whole simulated tests (best and median), the test time the best covered, how it ended."""

    best_s: float
    median_s: float
    simulated_s: float
    speed_x_real_time: float
    repeats: int
    verdict: str
    stop: str


@dataclass(frozen=True)
class RealtimeRun:
    """The bench loop against the rig process, and a bare loop at the same period, on one machine at one time."""

    bare: LoopFigures
    bench: LoopFigures


def simulated_test(variant: Variant, repeats: int, full_length: bool) -> SimulatedTiming:
    """Wall time of a whole simulated test of a new valve (everything in the loop, and its judgement), best and
    median of ``repeats``; ``simulated_s`` is the test time it covered (the early stop's, unless ``full_length``)."""
    from edc_bench.bench import run_simulated_test

    walls, covered = [], []
    for n in range(repeats):
        t0 = time.perf_counter()
        result = run_simulated_test(variant, "new", seed=n, full_length=full_length)
        walls.append(time.perf_counter() - t0)
        covered.append(result.outcome.ticks_run * variant.controller.period_s)
    best = int(np.argmin(walls))
    return SimulatedTiming(walls[best], float(np.median(walls)), covered[best], covered[best] / walls[best], repeats,
                           str(result.verdict), str(result.stop.reason))


class StealSampler:
    """Samples /proc/stat's steal in a child process (it never holds this process's GIL)."""

    def __init__(self, every_s: float = 0.02) -> None:
        self.every_s = every_s
        self._proc: subprocess.Popen[str] | None = None

    def __enter__(self) -> StealSampler:
        self._proc = subprocess.Popen([sys.executable, "-m", "edc_bench.perf.steal_sampler", str(self.every_s)],
                                      stdout=subprocess.PIPE, text=True)
        assert self._proc.stdout is not None
        self._proc.stdout.readline()  # started
        return self

    def __exit__(self, *exc: object) -> None:
        if self._proc is not None and self._proc.poll() is None:
            self._proc.terminate()

    def samples(self) -> np.ndarray:
        """Rows of (perf_counter_ns, steal seconds) so far; stops the sampler."""
        assert self._proc is not None
        self._proc.terminate()
        out, _ = self._proc.communicate(timeout=5)
        rows = [fields for fields in (line.split() for line in out.splitlines()) if len(fields) == 2]
        # the last line may have been cut by the terminate
        return np.array([(float(a), float(b)) for a, b in rows]) if rows else np.zeros((0, 2))


def stolen_mask(times_ns: np.ndarray, steal: np.ndarray) -> np.ndarray:
    """True for each time that falls in (or next to) a sampling window with steal."""
    if len(steal) < 2:
        return np.zeros(len(times_ns), dtype=bool)
    window = np.searchsorted(steal[:, 0], times_ns)  # sample after each time
    took = np.diff(steal[:, 1]) >= STEAL_WINDOW_MIN_S  # window j: between samples j and j+1
    bad = np.zeros(len(steal) + 1, dtype=bool)
    bad[1:-1] = took
    # the window containing the time, and its neighbours (samples are 20 ms apart)
    return bad[window] | bad[np.maximum(window - 1, 0)] | bad[np.minimum(window + 1, len(bad) - 1)]


def _keep_going(variant: Variant) -> Variant:
    """The variant with the loop's missed-reply aborts at their loosest: a benchmark measures the whole run.

    A real test stops after a few missing replies in a row; a benchmark on a
    machine that stalls now and then would then measure only up to the first
    stall. The rig's own watchdog and the heartbeat check still apply.
    """
    return with_changes(variant, {"acceptance": {"max_missed_replies_in_row": 100, "max_missed_reply_fraction": 1.0}},
                        "a benchmark's loose aborts")


def bare_loop(period_s: float, duration_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Wait for each deadline and nothing else. Returns lateness (s) and each deadline (perf_counter ns)."""
    ticks = int(round(duration_s / period_s))
    clock = RealTimeClock()
    late = np.empty(ticks)
    gc.collect()
    gc.disable()
    try:
        clock.start()
        for k in range(ticks):
            late[k] = clock.wait_until((k + 1) * period_s)
    finally:
        gc.enable()
    deadlines = clock.origin_ns + ((np.arange(ticks) + 1) * period_s * 1e9)
    return late, deadlines


@dataclass
class LoopFigures:
    """Timing of one loop."""

    ticks: int
    lateness_us: tuple[float, float, float, float]  # p50, p99, p99.9, max
    overruns: int
    overruns_outside_steal: int
    ticks_outside_steal: int
    steal_s: float
    reply_latency_us: tuple[float, float] | None = None  # p50, p99
    missed_replies: int = 0
    abort_reason: str | None = None


def _loop_figures(late_s: np.ndarray, times_ns: np.ndarray, steal: np.ndarray, period_s: float,
                  steal_s: float) -> LoopFigures:
    stolen = stolen_mask(times_ns, steal)
    over = late_s > period_s  # a gap's rows (NaN: never ran) count once, at the tick that ran late
    p50, p99, p999 = percentiles(late_s * 1e6, (50, 99, 99.9))
    return LoopFigures(
        ticks=len(late_s), lateness_us=(p50, p99, p999, float(np.nanmax(late_s) * 1e6) if np.isfinite(late_s).any()
                                       else float("nan")),
        overruns=int(over.sum()), overruns_outside_steal=int((over & ~stolen).sum()),
        ticks_outside_steal=int((~stolen).sum()), steal_s=steal_s,
    )


def realtime(variant_name: str | None, period_s: float, duration_s: float) -> RealtimeRun:
    """The bench loop against the rig process, and a bare loop, at ``period_s`` for ``duration_s`` each."""
    from edc_bench.bench import BenchOptions, run_bench_test
    from edc_bench.config import load_variant
    from edc_bench.protocol import default_icd
    from edc_bench.runtime.bus import open_bus
    from edc_bench.sim.process import rig_process

    variant = _keep_going(with_timing(load_variant(variant_name), period_s=period_s, duration_s=duration_s))
    icd = default_icd()
    with StealSampler() as sampler:
        steal0 = cpu_steal_s()
        late, deadlines = bare_loop(period_s, duration_s)
        bare_steal = cpu_steal_s() - steal0
        with rig_process(variant_name, "new", 0) as channel, open_bus({"interface": "slcan", "channel": channel},
                                                                      icd.bitrate) as bus:
            clock = RealTimeClock()
            result = run_bench_test(bus, clock, variant, BenchOptions(classify=False))
        steal = sampler.samples()
    bare = _loop_figures(late, deadlines, steal, period_s, bare_steal)
    trace = result.trace
    ticks_ns = clock.origin_ns + (result.outcome.ticks_start_s + trace["t_s"]) * 1e9
    bench = _loop_figures(trace["lateness_s"], ticks_ns, steal, period_s, result.outcome.cpu_steal_s)
    reply = trace["reply_latency_s"] * 1e6
    bench.reply_latency_us = tuple(percentiles(reply, (50, 99)))  # type: ignore[assignment]
    bench.missed_replies = result.outcome.missed_replies
    bench.abort_reason = result.outcome.abort_reason
    return RealtimeRun(bare, bench)


@dataclass
class LinkFigures:
    """A whole bench test through a slow link, or with host stalls injected."""

    verdict: str
    reasons: list[str]
    ticks_run: int
    reply_age_ticks: dict[int, int]
    replies_too_old: int
    gaps: int
    ticks_lost: int
    stalls_injected: int = 0
    late_after_gap_us: float = float("nan")  # worst lateness of the tick just after a gap: resynchronised?
    steal_s: float = 0.0
    rig_worst_gap_ms: float | None = None
    stop_check_max_us: float = float("nan")  # the early stop's longest call (NaN: no early stop)
    stop_reason: str = ""


def link_test(variant_name: str | None, duration_s: float, *, adapter: str = "none",
              stall_s: float = 0.0) -> LinkFigures:
    """A full real-time test of a new valve against the rig process, through ``adapter`` (the rig's
    ``--adapter``), with a ``stall_s`` host stall once a second when it is not 0.

    The variant's own acceptance applies (nothing loosened): this is what a
    technician would get.
    """
    from edc_bench.bench import BenchOptions, run_bench_test
    from edc_bench.config import load_variant
    from edc_bench.protocol import default_icd
    from edc_bench.runtime.bus import open_bus
    from edc_bench.sim.process import rig_process
    from edc_bench.testing.stalls import StallingClock

    variant = with_timing(load_variant(variant_name), duration_s=duration_s)
    status: dict[str, float] = {}
    clock: RealTimeClock | StallingClock = RealTimeClock()
    if stall_s > 0:
        clock = StallingClock(clock, stall_s=stall_s, every_s=1.0, first_s=min(2.5, duration_s / 2))
    with rig_process(variant_name, "new", 0, adapter, status) as channel, \
            open_bus({"interface": "slcan", "channel": channel}, default_icd().bitrate) as bus:
        result = run_bench_test(bus, clock, variant, BenchOptions(classify=True))
    outcome, trace = result.outcome, result.trace
    gap = trace["gap"].astype(bool)
    after = np.flatnonzero(gap[:-1] & ~gap[1:]) + 1  # first tick run after each gap
    late_after = trace["lateness_s"][after] * 1e6
    return LinkFigures(
        verdict=result.verdict, reasons=list(result.reasons), ticks_run=outcome.ticks_run,
        reply_age_ticks=dict(outcome.reply_age_ticks), replies_too_old=outcome.replies_too_old, gaps=outcome.gaps,
        ticks_lost=outcome.ticks_lost, stalls_injected=getattr(clock, "stalls", 0),
        late_after_gap_us=float(np.nanmax(late_after)) if len(late_after) else float("nan"),
        steal_s=outcome.cpu_steal_s, rig_worst_gap_ms=status.get("worst_gap_ms"),
        stop_check_max_us=_or_nan(result.timing.stop_check_max_us), stop_reason=result.stop.reason)


def _or_nan(value: float | None) -> float:
    return float("nan") if value is None else value


def age_percentile(ages: dict[int, int], q: float) -> float:
    """The ``q``-th percentile (0-100) of a reply-age histogram (age in ticks -> count)."""
    if not ages:
        return float("nan")
    keys = np.array(sorted(ages))
    counts = np.array([ages[k] for k in keys], dtype=float)
    cum = np.cumsum(counts) / counts.sum()
    return float(keys[np.searchsorted(cum, q / 100.0)])
