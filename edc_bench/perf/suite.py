"""The benchmark groups, each figure beside its reference and its target (issue #6; the session's, #53)."""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass

from edc_bench.history.url import scratch_history
from edc_bench.perf import GROUPS
from edc_bench.perf.figures import Figure, SessionLatency


@dataclass(frozen=True)
class Sizes:
    """How much each group measures."""

    ticks: int
    frames: int
    simulated_repeats: int
    realtime_s: float
    valves: int
    startup_repeats: int
    session_valves: int


FULL = Sizes(ticks=30_000, frames=50_000, simulated_repeats=3, realtime_s=60.0, valves=1000, startup_repeats=5,
             session_valves=12)
QUICK = Sizes(ticks=30_000, frames=3_000, simulated_repeats=1, realtime_s=3.0, valves=40, startup_repeats=1,
              session_valves=3)


def _tick(variant_name: str | None, sizes: Sizes) -> list[Figure]:
    from edc_bench.config import load_variant
    from edc_bench.perf.compute import tick_compute

    base = load_variant(variant_name)
    out = []
    for kind in ("rls", "gradient"):
        variant = base.model_copy(update={"estimator": base.estimator.model_copy(update={"kind": kind})})
        m = tick_compute(variant, sizes.ticks)
        met = m.p50_us <= 15.0 and m.p50_us <= 2.0 * m.floor_p50_us
        note = (f"p99 {m.p99_us:.1f} us (floor {m.floor_p99_us:.1f}); {m.ticks} ticks; "
                f"drive differs from the floor's by at most {m.max_drive_difference_v:.1e} V")
        out.append(Figure("tick", f"controller tick, PID + feedforward + {kind}, p50", m.p50_us, "us",
                          m.floor_p50_us, "the same arithmetic inlined", "<= 15 us and <= 2x floor", met, note))
    return out


def _codec(sizes: Sizes) -> list[Figure]:
    from edc_bench.perf.compute import codec
    from edc_bench.protocol import default_icd

    m = codec(default_icd(), sizes.frames)
    out = []
    for cost, what in ((m.encode, "BENCH_CMD encode"), (m.decode, "RIG_FEEDBACK decode")):
        out.append(Figure("codec", f"{what} + CRC, p50", cost.ours_us, "us", cost.struct_us,
                          "struct, same layout + CRC", "<= 3x struct", cost.ours_us <= 3.0 * cost.struct_us,
                          f"cantools {cost.cantools_us:.2f} us; {m.frames} frames"))
    return out


def _simulated(variant_name: str | None, sizes: Sizes) -> list[Figure]:
    from edc_bench.config import load_variant
    from edc_bench.perf.loops import simulated_test

    variant = load_variant(variant_name)
    out = []
    for full_length, name in ((True, "full-length"), (False, "early-stopped (the technician's)")):
        m = simulated_test(variant, sizes.simulated_repeats, full_length)
        # no target: one simulated test's speed served no user (it once made the tick's modules compiled at
        # install, #54); the suite's and CI's time are what it adds up to, and they are watched instead
        out.append(Figure(
            "simulated", f"simulated {name} test of {m.simulated_s:g} s, wall (best)", m.best_s, "s",
            m.simulated_s, "real time", "", None,
            f"{m.speed_x_real_time:.0f}x real time; median {m.median_s:.2f} s of {m.repeats}; ended: "
            f"{m.stop}; codec, lockstep bus, rig firmware, plant, controller, recording, analysis"))
    return out


def _realtime(variant_name: str | None, sizes: Sizes) -> list[Figure]:
    from edc_bench.perf.loops import realtime

    out = []
    for rate_hz in (1000, 2000):
        period_s = 1.0 / rate_hz
        m = realtime(variant_name, period_s, sizes.realtime_s)
        bare, bench = m.bare, m.bench
        ratio_ok = bench.lateness_us[1] <= 1.5 * bare.lateness_us[1]
        outside = bench.overruns_outside_steal / max(bench.ticks_outside_steal, 1)
        completed = bench.abort_reason is None
        tag = f"{rate_hz / 1000:g} kHz"
        out.append(Figure(
            "realtime", f"{tag} bench loop lateness p99", bench.lateness_us[1], "us", bare.lateness_us[1],
            "bare loop p99, same run", "<= 1.5x bare", ratio_ok and completed,
            f"p50 {bench.lateness_us[0]:.0f}, p99.9 {bench.lateness_us[2]:.0f}, max {bench.lateness_us[3]:.0f} us "
            f"(bare {bare.lateness_us[0]:.0f}/{bare.lateness_us[2]:.0f}/{bare.lateness_us[3]:.0f}); "
            f"{bench.ticks} ticks" + ("" if completed else f"; ABORTED: {bench.abort_reason}")))
        out.append(Figure(
            "realtime", f"{tag} overruns outside CPU steal", 100.0 * outside, "%",
            100.0 * bare.overruns_outside_steal / max(bare.ticks_outside_steal, 1), "bare loop, same run",
            "< 0.1 %", outside < 0.001 and completed,
            f"{bench.overruns} overruns in all ({bare.overruns} bare); steal {bench.steal_s:.2f} s "
            f"(bare {bare.steal_s:.2f} s); reply latency p50 {bench.reply_latency_us[0]:.0f} us, "
            f"p99 {bench.reply_latency_us[1]:.0f} us; missed replies {bench.missed_replies}"))
    out += _links(variant_name, sizes)
    return out


def _links(variant_name: str | None, sizes: Sizes) -> list[Figure]:
    """Whole tests as a technician runs them: through a USB adapter, and with 5 ms host stalls."""
    from edc_bench.perf.loops import age_percentile, link_test

    duration_s = max(sizes.realtime_s / 2.0, 3.0)
    usb = link_test(variant_name, duration_s, adapter="usb-fs")
    stalls = link_test(variant_name, duration_s, stall_s=0.005)
    machine = (f"steal {usb.steal_s:.2f} s, rig's worst serve gap {usb.rig_worst_gap_ms} ms, "
               f"{usb.gaps} host stalls lost {usb.ticks_lost} ticks")
    recovered = stalls.late_after_gap_us < 1e3
    return [
        Figure("realtime", f"usb-fs adapter, a test of up to {duration_s:g} s: reply age p99", age_percentile(usb.reply_age_ticks, 99),
               "ticks", age_percentile(usb.reply_age_ticks, 50), "reply age p50", "test valid (PASS on a new valve)",
               usb.verdict == "PASS",
               f"{usb.verdict} {'; '.join(usb.reasons)}; ended: {usb.stop_reason} after {usb.ticks_run} ticks, the "
               f"early stop's longest check {usb.stop_check_max_us:.0f} us; ages {usb.reply_age_ticks}; "
               f"{usb.replies_too_old} too old (never used); {machine}"),
        Figure("realtime", f"5 ms host stall every second, a test of up to {duration_s:g} s: ticks lost per gap "
               "(the machine's own gaps too)",
               stalls.ticks_lost / max(stalls.gaps, 1), "ticks", 5.0, "ticks in 5 ms",
               "test valid, back on time after each gap", stalls.verdict == "PASS" and recovered,
               f"{stalls.verdict} {'; '.join(stalls.reasons)}; {stalls.stalls_injected} stalls injected, "
               f"{stalls.gaps} gaps (the machine's own included), {stalls.ticks_lost} ticks lost; worst lateness "
               f"of the tick after a gap {stalls.late_after_gap_us:.0f} us; steal {stalls.steal_s:.2f} s, rig's "
               f"worst serve gap {stalls.rig_worst_gap_ms} ms"),
    ]


def _throughput(variant_name: str | None, sizes: Sizes) -> list[Figure]:
    from edc_bench.perf.throughput import bare_python_time, batch, help_time, time_to_first_tick

    workers = os.cpu_count() or 1
    b = batch(variant_name, sizes.valves, workers)
    python_s = bare_python_time(sizes.startup_repeats)
    h = help_time(sizes.startup_repeats)
    first = time_to_first_tick(sizes.startup_repeats)
    return [
        Figure("throughput", f"batch path, {workers} processes", b.per_minute_pool, "tests/min", None, "",
               ">= 20,000 / min", b.per_minute_pool >= 20_000,
               f"each test stopped where the bench's early stop ends it (mean {b.mean_stop_s:.1f} s, median "
               f"{b.median_stop_s:g} s of {b.full_length_s:g} s); one process: "
               f"{b.per_minute_one_process:.0f} / min; every test at full length, one process: "
               f"{b.per_minute_full_length:.0f} / min; {b.valves} valves per process"),
        Figure("throughput", "edc-bench --help (best)", h.best_s, "s", python_s, "python -c pass", "< 0.3 s",
               h.best_s < 0.3, f"median {h.median_s:.2f} s of {h.repeats}"),
        Figure("throughput", "edc-bench test to its first tick (best)", first.best_s, "s", python_s,
               "python -c pass", "<= 0.5 s", first.best_s <= 0.5,
               f"median {first.median_s:.2f} s of {first.repeats}; simulated rig; the gain check's margins "
               f"cached (first run on a station, computing them: {first.cold_s:.2f} s)"),
    ]


def _session(sizes: Sizes, session_latency: Callable[[int], SessionLatency] | None) -> list[Figure]:
    if session_latency is None:
        raise RuntimeError("the session's measurement was not given (edc-bench perf passes it)")
    m = session_latency(sizes.session_valves)
    (decision_p50, decision_max), (report_p50, report_max) = m.decision_s, m.report_s
    return [
        Figure("session", "a test's safe stop to its decision on screen, worst", decision_max, "s", report_max,
               "its reports drawn, worst", "<= 0.5 s", decision_max <= 0.5,
               f"median {decision_p50:.2f} s; reports drawn after the decision, median {report_p50:.2f} s from the "
               f"safe stop; {m.valves} valves, {m.tests} tests on the simulated rig, the app headless; "
               "judgement, record, history row and screen update included"),
    ]


def run(groups: tuple[str, ...] = GROUPS, *, quick: bool = False, variant_name: str | None = None,
        on_figure: Callable[[Figure], None] | None = None,
        session_latency: Callable[[int], SessionLatency] | None = None) -> list[Figure]:
    """Run the chosen groups; ``on_figure`` sees each figure as soon as it is measured. ``session_latency`` is
    :func:`edc_bench.session.latency.session_latency`, passed in by the command: the session's app sits above this
    layer (it runs the rig self-check)."""
    sizes = QUICK if quick else FULL
    steps: dict[str, Callable[[], list[Figure]]] = {
        "tick": lambda: _tick(variant_name, sizes),
        "codec": lambda: _codec(sizes),
        "simulated": lambda: _simulated(variant_name, sizes),
        "realtime": lambda: _realtime(variant_name, sizes),
        "throughput": lambda: _throughput(variant_name, sizes),
        "session": lambda: _session(sizes, session_latency),
    }
    figures: list[Figure] = []
    with scratch_history():  # the benchmark's tests are no shop's: none of them reaches the station's history
        for group in groups:
            try:
                measured = steps[group]()
            except Exception as exc:
                measured = [Figure(group, "group failed", float("nan"), "", target="runs", met=False,
                                   note=f"{type(exc).__name__}: {exc}")]
            for figure in measured:
                figures.append(figure)
                if on_figure is not None:
                    on_figure(figure)
    return figures
