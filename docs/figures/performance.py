"""docs/performance.md's figures: a full run of ``edc-bench perf``, where a simulated test's time goes, a batch's."""

from __future__ import annotations

import cProfile
import json
import pstats
import subprocess
import sys
from collections import defaultdict
from collections.abc import Callable
from typing import Any

import numpy as np

from figures.common import measured_on, measurement, stored, stored_record, table, wrap


@measurement("performance-perf", minutes=7, timing=True)
def perf_run() -> dict:
    """``edc-bench perf --json``, the full run, as it printed it (figures and environment)."""
    done = subprocess.run([sys.executable, "-m", "edc_bench", "perf", "--json"], capture_output=True, text=True,
                          check=False)
    if done.returncode != 0:
        raise RuntimeError(f"edc-bench perf failed ({done.returncode}):\n{done.stderr[-3000:]}")
    return json.loads(done.stdout)


@measurement("performance-session", minutes=1, timing=True)
def session_run() -> dict:
    """``edc-bench perf --only session --json``: the session's safe stop to its decision on screen, and its report."""
    done = subprocess.run([sys.executable, "-m", "edc_bench", "perf", "--only", "session", "--json"],
                          capture_output=True, text=True, check=False)
    if done.returncode not in (0, 1):  # 1: a target missed, which the figure says
        raise RuntimeError(f"edc-bench perf failed ({done.returncode}):\n{done.stderr[-3000:]}")
    return json.loads(done.stdout)


def session_latency() -> str:
    """The stored session figure, in a sentence for docs/station.md."""
    (figure,) = stored("performance-session")["figures"]
    met = "within" if figure["met"] else "**not** within"
    return wrap(f"{measured_on('performance-session')} Worst time from a test's safe stop to its decision on screen: "
                f"{figure['value']:.2f} s ({met} the 0.5 s target); its reports were drawn {figure['reference']:.1f} s "
                f"after the safe stop at the worst ({figure['note'].split('; ', 1)[0]}; "
                f"{figure['note'].split('; ')[2]}).")


def _value(value: float | None, unit: str) -> str:
    if value is None:
        return ""
    if value != value:  # NaN: the group failed
        return "failed"
    if 0 < abs(value) < 0.1:  # a small share: its first figures, not "0.00"
        return f"{value:.2g} {unit}".strip()
    digits = 0 if abs(value) >= 100 else 1 if abs(value) >= 10 else 2
    return f"{value:,.{digits}f} {unit}".strip()


def perf_table() -> str:
    """The stored run's figures, each beside its reference and target, and whether it met it."""
    run = stored("performance-perf")
    rows = []
    for f in run["figures"]:
        reference = _value(f["reference"], f["unit"]) + (f" ({f['reference_name']})" if f["reference_name"] else "")
        met = "" if f["met"] is None else "yes" if f["met"] else "**no**"
        rows.append((f["group"], f["name"], _value(f["value"], f["unit"]), reference, f["target"], met,
                     f["note"].replace("|", "/")))
    return table(("group", "figure", "measured", "reference, same run", "target", "met", "notes"), rows)


def perf_environment() -> str:
    """When and where the stored run was made, and how much CPU the hypervisor took meanwhile."""
    env = stored("performance-perf")["environment"]
    return wrap(f"{measured_on('performance-perf')} edc-bench {env['edc_bench']}; `{env['command']}` "
                f"started at {env['date']}; the hypervisor took {env['cpu_steal_s']:.1f} s of CPU during the run "
                f"(CPU steal, as /proc/stat counts it).")


#: Where a simulated test's time goes, by the code's job (the first match of a function's file wins).
PROFILE_PARTS = (
    ("the simulated rig: firmware prototype", "firmware_proto/"),
    ("the simulated rig: plant, sensors, adapter, runner", "edc_bench/sim/"),
    ("the controller (PID, feedforward, estimator)", "edc_bench/control/"),
    ("the tick engine (reply matching, trace, checks)", "edc_bench/engine/"),
    ("the loop's shell and clock", "edc_bench/runtime/"),
    ("frame codec and CRC", "edc_bench/protocol/"),
    ("identification, judgement, early stop", "edc_bench/identification/"),
    ("identification, judgement, early stop", "edc_bench/verdict/"),
    ("python-can (messages, bus base class)", "/can/"),
    ("numpy and scipy", "/numpy/"),
    ("numpy and scipy", "/scipy/"),
)


@measurement("performance-profile", minutes=0.5, timing=True)
def profile_simulated_test() -> dict:
    """Share of a full-length default simulated test's own time (cProfile's tottime) by the code's job."""
    from edc_bench.bench import run_simulated_test
    from edc_bench.config import load_variant
    variant = load_variant("p-edc-default")
    run_simulated_test(variant, "new", 1, full_length=True)  # warm: imports, the gain check's cache
    profiler = cProfile.Profile()
    profiler.enable()
    run_simulated_test(variant, "new", 1, full_length=True)
    profiler.disable()
    shares: dict[str, float] = defaultdict(float)
    stats = pstats.Stats(profiler).stats  # type: ignore[attr-defined]
    for (path, _, _), (_, _, tottime_s, _, _) in stats.items():
        part = next((name for name, piece in PROFILE_PARTS if piece in path.replace("\\", "/")), "Python built-ins and the rest")
        shares[part] += tottime_s
    total_s = sum(shares.values())
    return {"total_s": round(total_s, 2),
            "shares": {part: round(seconds / total_s, 3) for part, seconds in sorted(shares.items())}}


def _shares_table(shares: dict[str, float], part: str, share: str) -> str:
    """A table of shares (0..1) by part, largest first."""
    rows = sorted(shares.items(), key=lambda item: -item[1])
    return table((part, share), [(name, f"{value:.0%}") for name, value in rows])


def profile_table() -> str:
    """The profile's shares, largest first."""
    result = stored("performance-profile")
    return "\n".join([_shares_table(result["shares"], "part of the code", "share of the test's time"), "",
                      wrap(f"{measured_on('performance-profile')} Total {result['total_s']:.2f} s under the "
                           f"profiler, which slows Python calls more than numpy's.")])


#: Where a batch's time goes: the functions of the batch path timed (a class's method, or a function of the module
#: when no class is named), each with the part of the work it is. A part's time is its own: what a part it calls
#: takes (the heating's matrix exponentials) is counted there.
BATCH_PARTS = (
    ("the period fit: rows and normal equations (identification)", "_RowFeeder", "sample"),
    ("the controller (the law over arrays)", "_Controller", "step"),
    ("the plant (compiled step)", "_VectorPlant", "advance_period"),
    ("the plant's matrix exponentials (at the start, and again as the coils warm)", "", "expm"),
    ("the coils' heating (without the exponentials)", "_VectorPlant", "add_heat"),
    ("the sensors (rack and current, noise)", "_Sensors", "sample"),
    ("the sensors (rack and current, noise)", "_Sensors", "current"),
    ("the stop rule (fit solved, judged)", "_BatchRun", "_periods_done"),
)
#: The rest of a batch's wall time: what no part above times.
BATCH_REST = "the rest (tick bookkeeping, numpy's call costs)"


@measurement("performance-batch-profile", minutes=0.5, timing=True)
def profile_batch() -> dict:
    """Share of an early-stopped batch's wall time (1,000 default valves, one process) by part; how much of it the
    tests still running after nine in ten have stopped take (the tail), and the tail's own shares."""
    import time

    from edc_bench.config import load_variant
    from edc_bench.population import batch
    from edc_bench.population.batch_stop import BatchStopRule
    from edc_bench.population.valves import draw_population

    variant = load_variant("p-edc-default")
    valves = draw_population(variant, 1000, 7)
    rule = BatchStopRule.shipped(variant)
    batch.run_batch(variant, valves[:4], list(range(4)), stop=rule)  # warm: imports, the compiled kernels
    spent: dict[str, float] = defaultdict(float)
    spent_in_tail: dict[str, float] = defaultdict(float)
    inner_s = [0.0]  # time taken by timed parts inside the part now running (not its own)
    tail = {"from_s": None}
    owners = [(batch if not cls else getattr(batch, cls), name) for _, cls, name in BATCH_PARTS]
    saved = [(owner, name, getattr(owner, name)) for owner, name in owners]

    def timed(part: str, function: Callable[..., Any]) -> Callable[..., Any]:
        def run(*args: Any, **kwargs: Any) -> Any:
            outer_inner, inner_s[0] = inner_s[0], 0.0
            t0 = time.perf_counter()
            try:
                return function(*args, **kwargs)
            finally:
                took = time.perf_counter() - t0
                spent[part] += took - inner_s[0]
                if tail["from_s"] is not None:
                    spent_in_tail[part] += took - inner_s[0]
                inner_s[0] = outer_inner + took
        return run

    original_rig_period = batch._BatchRun._rig_period

    def rig_period(run: Any, k: int, u: np.ndarray) -> int:
        if tail["from_s"] is None and len(run.alive) <= len(valves) // 10:
            tail["from_s"] = time.perf_counter()
        return original_rig_period(run, k, u)

    try:
        for (part, _, _), (owner, name) in zip(BATCH_PARTS, owners):
            setattr(owner, name, timed(part, getattr(owner, name)))
        batch._BatchRun._rig_period = rig_period
        t0 = time.perf_counter()
        result = batch.run_batch(variant, valves, list(range(len(valves))), stop=rule)
        end_s = time.perf_counter()
    finally:
        for owner, name, original in saved:
            setattr(owner, name, original)
        batch._BatchRun._rig_period = original_rig_period
    total_s = end_s - t0
    spent[BATCH_REST] = total_s - sum(spent.values())
    tail_s = 0.0 if tail["from_s"] is None else end_s - tail["from_s"]
    if tail_s > 0.0:
        spent_in_tail[BATCH_REST] = tail_s - sum(spent_in_tail.values())
    return {"valves": len(valves), "total_s": round(total_s, 2),
            "shares": {part: round(seconds / total_s, 3) for part, seconds in sorted(spent.items())},
            "tail_share": round(tail_s / total_s, 3), "tail_valves": int(sum(result.stop.time_s > 12.5)),
            "tail_shares": {part: round(seconds / tail_s, 3) for part, seconds in sorted(spent_in_tail.items())},
            "median_stop_s": float(np.median(result.stop.time_s))}


def batch_profile_table() -> str:
    """The batch's shares, largest first, and its tail's (the ticks after nine in ten tests had stopped)."""
    result = stored("performance-batch-profile")
    tail = result["tail_shares"]
    first, second = sorted(tail, key=lambda part: -tail[part])[:2]
    return "\n".join([
        _shares_table(result["shares"], "part of the batch path", "share of the batch's time"), "",
        wrap(f"{measured_on('performance-batch-profile')} {result['valves']:,} default valves, each stopped where "
             f"the bench's early stop ends it (median {result['median_stop_s']:g} s), in {result['total_s']:.2f} s; "
             f"{result['tail_share']:.0%} of that time went to the ticks after nine in ten had stopped "
             f"({result['tail_valves']} tests ran past 12.5 s), and of that tail, {tail[first]:.0%} to {first} "
             f"and {tail[second]:.0%} to {second}.")])


def recorded_command() -> str:
    """The command line the stored run was made with (for the text)."""
    return stored_record("performance-perf")["command"]


@measurement("performance-web", minutes=3, timing=True)
def web_run() -> dict:
    """``python -m edc_bench.web.benchmark --json``: the web view's pages on a chain of 100 stations and a million
    tests in a throw-away PostgreSQL server."""
    done = subprocess.run([sys.executable, "-m", "edc_bench.web.benchmark", "--tests", "1000000", "--requests", "20",
                           "--json"], capture_output=True, text=True, check=False)
    if done.returncode != 0:
        raise RuntimeError(f"the web benchmark failed ({done.returncode}):\n{done.stderr[-3000:]}")
    return json.loads(done.stdout)


def web_table() -> str:
    """The stored web benchmark: each page's median and 95th percentile against the 300 ms target."""
    result = stored("performance-web")
    rows = [(page["page"], f"{page['p50_ms']:.0f} ms", f"{page['p95_ms']:.0f} ms", "yes" if page["met"] else "no")
            for page in result["pages"]]
    written = result["written"]
    return (wrap(f"{measured_on('performance-web')} {written['tests']:,} tests of {written['stations']} stations "
                 f"and {written['checks']:,} self-checks, copied in {result['fill_s']:.0f} s; "
                 f"{result['pages'][0]['requests']} timed requests a page after one to warm it, through the "
                 "application in process (no network), signed in as the database's owner.") + "\n\n"
            + table(("page", "p50", "p95", f"p95 <= {result['target_p95_ms']:.0f} ms"), rows))
