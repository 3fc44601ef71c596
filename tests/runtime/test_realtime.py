"""A real-time bench test over slcan against the rig process (`edc-bench test --realtime`); slow: `pytest -m slow`."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from helpers import REPO, edc_bench
from realtime_judge import attempts, disturbance, figures

from edc_bench.config import load_variant
from edc_bench.physics.feedforward import feedforward_truth
from edc_bench.physics.valve import parse_valve_spec, plant_parameters

@pytest.mark.slow
@pytest.mark.realtime
def test_realtime_test_over_slcan_against_the_rig_process(tmp_path: Path) -> None:
    """`edc-bench test --realtime` starts `edc-bench rig` and drives it over slcan/TCP at 1 kHz.

    This shared 2-core VM stalls processes for milliseconds at times (CPU steal, slow
    wake-ups); the default acceptance aborts after 5 replies missing in a row. This test
    checks the real-time path, so its variant tolerates 50 in a row; the record still
    counts every missed reply and overrun. Up to three attempts, each reported. A run that
    does not complete although the machine ran it undisturbed (tests/realtime_judge.py)
    fails the test; if every attempt was disturbed, the test is skipped with the measured
    figures.
    """
    source = (REPO / "configs" / "p-edc-default.toml").read_text()
    variant_file = tmp_path / "rt.toml"
    variant_file.write_text(source.replace('name = "p-edc-default"', 'name = "rt-test"')
                            + "\n[acceptance]\nmax_missed_replies_in_row = 50\nmax_overrun_fraction = 0.2\n"
                            "max_missed_reply_fraction = 0.2\n")
    last: dict = {}

    def run():
        proc = edc_bench("test", "--realtime", "--variant", str(variant_file), "--valve", "worn",
                         "--duration-s", "12", "--json", "--no-figure", "--out", "rec", cwd=tmp_path)
        assert proc.returncode in (11, 12), proc.stderr  # a worn valve: FAIL, or INVALID if disturbed
        summary = json.loads(proc.stdout)
        timing = summary["timing"]
        doc = json.loads(Path(tmp_path / summary["record_dir"], "record.json").read_text())
        rig, loop = doc["simulation"]["rig_process"], doc["loop"]
        # every run, complete or not, leaves its timing statistics in the record and the rig safe
        assert summary["clock"] == "real-time"
        for key in ("lateness_p50_us", "lateness_p99_us", "lateness_max_us", "ticks_late", "missed_replies",
                    "cpu_steal_s"):
            assert key in timing
        assert doc["timing"] == timing
        assert loop["safe_confirmed"] is True
        assert doc["firmware_version"] == "1.0"
        last.update(summary=summary)
        # complete: ticks lost to host stalls are gaps in a complete run, not an end
        completed = loop["ticks_run"] == 12_000 and not loop["abort_reason"]
        return (completed, f"{summary['verdict']} {summary['reasons']}, {figures(timing, rig)}",
                disturbance(timing, rig, (loop["ticks_lost"], loop["ticks_run"])))

    assert attempts(run, "real time over slcan"), "the real-time test did not complete on an undisturbed machine"
    summary = last["summary"]
    timing = summary["timing"]
    assert timing["missed_replies"] < 1200
    # identification in real time: the rig process runs the worn preset, whose truth is known here
    variant = load_variant()
    truth = feedforward_truth(plant_parameters(variant, parse_valve_spec("worn", variant)))
    assert abs(summary["features"]["af"] / truth.af - 1) < 0.08
    assert abs(summary["features"]["a1"] / truth.a1 - 1) < 0.20


@pytest.mark.slow
@pytest.mark.realtime
def test_realtime_full_test_through_a_usb_adapter_passes_a_new_valve(tmp_path: Path) -> None:
    """`edc-bench test --realtime --adapter usb-fs`: the rig process holds frames back as a USB full-speed adapter
    does (1.5-3.5 ms round trip); the shipped variant, as shipped and as a technician runs it (the early stop on,
    its checks in real time), completes its test and passes a new valve."""
    def run():
        proc = edc_bench("test", "--realtime", "--adapter", "usb-fs", "--valve", "new", "--json", "--no-figure",
                         "--no-history", "--out", "rec", cwd=tmp_path, timeout=180)
        assert proc.returncode in (0, 12), proc.stderr  # PASS, or INVALID when the machine got in the way
        summary = json.loads(proc.stdout)
        doc = json.loads(Path(tmp_path / summary["record_dir"], "record.json").read_text())
        loop = doc["loop"]
        completed = summary["verdict"] == "PASS"
        description = (f"{summary['verdict']} {summary['reasons']}, reply ages {loop['reply_age_ticks']}, "
                       f"{loop['replies_too_old']} too old, {loop['gaps']} gaps")
        if completed:
            # ended when the verdict was certain, at the end of a whole period, or at the full 30 s
            stop = doc["stop"]
            assert stop["reason"] in ("verdict certain", "full length"), stop
            # decided beside the ticks, after the period it judged, and ended at the tick that took the decision
            assert stop["time_s"] <= stop["decided_s"] and loop["safe_confirmed"]
            assert loop["ticks_run"] == round(stop["decided_s"] * 1000)
            assert stop["reason"] == "verdict certain" or loop["ticks_run"] == 30_000
            assert max(map(int, loop["reply_age_ticks"])) >= 2  # the adapter's latency was there
        rig = doc["simulation"]["rig_process"]
        # the rig process not serving for as many ticks as the missed-reply limit allows in a row can end the
        # test by itself; that is the machine, not the bench
        return (completed, f"{description}, {figures(summary['timing'], rig)}",
                disturbance(summary["timing"], rig, (loop["ticks_lost"], loop["ticks_run"])))

    assert attempts(run, "USB adapter, real time"), "an undisturbed real-time run through usb-fs did not PASS"


@pytest.mark.slow
@pytest.mark.realtime
def test_realtime_host_stall_of_5_ms_every_second_leaves_the_test_valid() -> None:
    """A bench PC that stalls 5 ms once a second (really: the process sleeps): each stall is a gap of about five
    ticks, the loop resynchronises, and the test completes valid (PASS on a new valve). Full length (15 s here), so
    every run sees at least 12 stalls."""
    from edc_bench.bench import BenchOptions, run_bench_test
    from edc_bench.protocol import default_icd
    from edc_bench.runtime.bus import open_bus
    from edc_bench.runtime.clock import RealTimeClock
    from edc_bench.sim.process import rig_process
    from edc_bench.testing.stalls import StallingClock

    variant = load_variant()
    variant = variant.model_copy(update={"excitation": variant.excitation.model_copy(update={"duration_s": 15.0})})

    def run():
        status: dict[str, float] = {}
        with rig_process(None, "new", 0, "none", status) as channel, \
                open_bus({"interface": "slcan", "channel": channel}, default_icd().bitrate) as bus:
            clock = StallingClock(RealTimeClock(), stall_s=0.005, every_s=1.0, first_s=2.5)
            result = run_bench_test(bus, clock, variant, BenchOptions(full_length=True))
        outcome = result.outcome
        description = (f"{result.verdict} {result.reasons}, {clock.stalls} stalls injected, {outcome.gaps} gaps, "
                       f"{outcome.ticks_lost} ticks lost, reply ages {outcome.reply_age_ticks}")
        completed = result.verdict == "PASS"
        if completed:
            assert result.stop.reason == "full length"
            assert outcome.ticks_run == 15_000 and clock.stalls >= 12
            assert outcome.gaps >= clock.stalls  # every injected stall shows as a gap (the machine may add some)
            assert 4 * clock.stalls <= outcome.ticks_lost
        # ticks the machine lost by itself, beyond the injected stalls (each costs 5 ticks, 6 with the wake-up),
        # spend the overrun budget the injected ones are checked against
        own_lost = outcome.ticks_lost - 6 * clock.stalls
        return (completed, f"{description}, {figures(result.timing, status)}",
                disturbance(result.timing, status, (own_lost, outcome.ticks_run)))

    assert attempts(run, "5 ms host stalls"), "an undisturbed real-time run with 5 ms stalls was not a valid PASS"


@pytest.mark.slow
@pytest.mark.realtime
def test_a_realtime_test_started_as_a_technician_starts_it_runs_at_real_time_priority(tmp_path: Path) -> None:
    """`edc-bench test --realtime`, typed without chrt: the bench raises its own priority where the PC permits and
    the simulated rig process is put above it; the tests are valid with the shipped acceptance. Typed by hand,
    `chrt -f 50` had given 3 of 3 valid tests where the same tests at normal priority on a loaded PC were INVALID."""
    import subprocess
    import sys

    from edc_bench.runtime.priority import realtime_permitted

    if not realtime_permitted():
        pytest.skip("real-time priority is not permitted to this user here: the bench says what the administrator "
                    "runs (tests/runtime/test_priority.py)")

    def run():
        proc = subprocess.run([sys.executable, "-m", "edc_bench", "test", "--realtime",
                               "--valve", "worn", "--duration-s", "12", "--json", "--no-figure", "--no-history",
                               "--out", "rec"], capture_output=True, text=True, cwd=tmp_path, timeout=300)
        summary = json.loads(proc.stdout)
        doc = json.loads(Path(tmp_path / summary["record_dir"], "record.json").read_text())
        rig, loop = doc["simulation"]["rig_process"], doc["loop"]
        assert summary["timing"]["scheduling"] == "real-time (SCHED_FIFO 50, raised by the bench)"
        if summary["verdict"] == "FAIL":
            assert proc.returncode == 11  # valid: a worn valve judged FAIL at the bench's own priority
        return (summary["verdict"] == "FAIL", f"{summary['verdict']} {summary['reasons'][:2]}, "
                f"{figures(summary['timing'], rig)}",
                disturbance(summary["timing"], rig, (loop["ticks_lost"], loop["ticks_run"])))

    assert attempts(run, "a real-time test at the bench's own priority"), \
        "a real-time test at the bench's own priority was invalid on an undisturbed machine"


def gap_runs(gap) -> list[tuple[int, int]]:
    """The host stalls in a trace's gap column: (first tick lost, ticks lost) for each run of gap rows."""
    import numpy as np

    flags = np.concatenate(([0], np.asarray(gap, dtype=np.int8) != 0, [0])).astype(np.int8)
    edges = np.flatnonzero(np.diff(flags))
    return [(int(a), int(b - a)) for a, b in zip(edges[::2], edges[1::2])]


def test_gap_runs_finds_each_stall() -> None:
    assert gap_runs([0, 1, 1, 0, 0, 1, 0, 1]) == [(1, 2), (5, 1), (7, 1)]
    assert gap_runs([0, 0]) == []


@pytest.mark.slow
@pytest.mark.realtime
def test_a_slow_pcs_early_stop_decision_costs_no_ticks_and_never_trips_the_watchdog(monkeypatch) -> None:
    """A PC on which the early stop's decision at a period's end takes 30 ms of CPU (CI's Xeon took up to 22 ms):
    inside the tick that tripped the rig's 20 ms watchdog (CI: "rig fault: watchdog tripped") and lost ticks at
    every period's end. Beside the ticks (runtime.stop_worker) the test completes valid, the decision taken after
    the period it judged."""
    import time

    from edc_bench.bench import BenchOptions, run_bench_test
    from edc_bench.identification.period_fit import FitSetup
    from edc_bench.protocol import default_icd
    from edc_bench.runtime.bus import open_bus
    from edc_bench.runtime.clock import RealTimeClock
    from edc_bench.sim.process import rig_process
    from edc_bench.verdict.early_stop import EarlyStop

    check = EarlyStop.check
    slow_calls = []

    def slow_check(self, k, columns):
        if k in self.period_ends:  # the decision: 30 ms of CPU, holding the interpreter as Python code does
            began = time.perf_counter()
            while time.perf_counter() - began < 0.030:
                pass
            slow_calls.append(k)
        return check(self, k, columns)

    monkeypatch.setattr(EarlyStop, "check", slow_check)
    variant = load_variant()
    setup = FitSetup.from_variant(variant)
    period_ends = [setup.end_tick(p) for p in range(1, setup.blocks_in(setup.end_tick(40) + 1) + 1)]

    def run():
        status: dict[str, float] = {}
        slow_calls.clear()
        with rig_process(None, "new", 0, "none", status) as channel, \
                open_bus({"interface": "slcan", "channel": channel}, default_icd().bitrate) as bus:
            result = run_bench_test(bus, RealTimeClock(), variant, BenchOptions())
        outcome = result.outcome
        stalls = gap_runs(result.trace["gap"])
        completed = result.verdict == "PASS"
        if completed:
            assert slow_calls and result.stop.reason == "verdict certain"
            assert result.stop.time_s < result.stop.decided_s  # taken beside the ticks, after its period
            assert outcome.ticks_run == round(result.stop.decided_s / variant.controller.period_s)
        # ticks lost just after a period's end are the decision's (this test's subject), never the machine's
        machine_stalls = [lost for k, lost in stalls if not any(0 < k - end <= 50 for end in period_ends)]
        machine_lost = sum(machine_stalls)
        if any("watchdog" in reason.lower() for reason in result.reasons):
            # only a stall of 15 ms or more (of the bench or of the rig process) trips its 20 ms watchdog
            assert max(machine_stalls, default=0) >= 15 or (status.get("worst_gap_ms") or 0) >= 15, \
                f"the rig's watchdog tripped, and no stall of this machine was long enough to trip it: {result.reasons}"
        description = (f"{result.verdict} {result.reasons}, {len(slow_calls)} slow decisions, stalls {stalls}, "
                       f"{figures(result.timing, status)}")
        return completed, description, disturbance(result.timing, status, (machine_lost, outcome.ticks_run))

    assert attempts(run, "30 ms decisions"), "an undisturbed real-time test with 30 ms decisions was not a valid PASS"


@pytest.mark.slow
@pytest.mark.realtime
def test_a_decision_for_the_last_tick_is_taken_in_real_time_as_in_simulated_time() -> None:
    """A test of 10 s: its third period, the first the early stop decides on, ends at its last tick. In simulated
    time the rule decides inside that tick ("verdict certain" at 10 s); in real time the worker decides after the
    loop's last poll, and the decision must still be taken, not recorded as "full length" (a review found it was)."""
    from edc_bench.bench import BenchOptions, run_bench_test, run_simulated_test
    from edc_bench.protocol import default_icd
    from edc_bench.runtime.bus import open_bus
    from edc_bench.runtime.clock import RealTimeClock
    from edc_bench.sim.process import rig_process

    variant = load_variant()
    variant = variant.model_copy(update={"excitation": variant.excitation.model_copy(update={"duration_s": 10.0})})
    simulated = run_simulated_test(variant, "new")
    assert simulated.stop.reason == "verdict certain" and simulated.outcome.ticks_run == 10_000

    def run():
        status: dict[str, float] = {}
        with rig_process(None, "new", 0, "none", status) as channel, \
                open_bus({"interface": "slcan", "channel": channel}, default_icd().bitrate) as bus:
            result = run_bench_test(bus, RealTimeClock(), variant, BenchOptions())
        outcome = result.outcome
        completed = result.verdict == "PASS"
        if completed:
            assert result.stop.reason == "verdict certain", result.stop
            assert result.stop.time_s == pytest.approx(10.0) and result.stop.decided_s == pytest.approx(10.0)
        return (completed, f"{result.verdict} {result.reasons}, stop {result.stop}, {figures(result.timing, status)}",
                disturbance(result.timing, status, (outcome.ticks_lost, outcome.ticks_run)))

    assert attempts(run, "a decision at the last tick"), "an undisturbed real-time test of 10 s did not PASS"
