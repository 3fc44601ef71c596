"""A real-time bench test over slcan against the rig process (`edc-bench test --realtime`); slow: `pytest -m slow`."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from helpers import REPO, edc_bench

from edc_bench.config import load_variant
from edc_bench.physics.feedforward import feedforward_truth
from edc_bench.physics.valve import parse_valve_spec, plant_parameters

STEAL_LIMIT_S = 0.15  # CPU steal during one 12 s run above which real-time figures say nothing about the code
STALL_LIMIT_US = 10_000  # a bench tick this late means the machine did not run the process
RIG_GAP_LIMIT_MS = 10.0  # the rig process went this long (half its watchdog) without serving: not run by the machine
# with the shipped acceptance a test ends when 6 commands in a row pass the 4 ms age limit with no reply at all:
# a rig process that does not serve for 8 ms (less the adapter's round trip) gets there
LINK_GAP_LIMIT_MS = 8.0
# a bench process that lost more than 1 tick in 500 to stalls of its own (each a whole period late) was not given
# its 1 kHz by this machine: the shipped acceptance allows 1 % of ticks, and the stall test spends half of that
OWN_LOSS_LIMIT = 0.002
OWN_LOSS_MIN_TICKS = 5  # below this a short (aborted) run's own losses say nothing: one stall of 1 ms is not a machine


def lost_too_many(lost: int, ticks_run: int) -> bool:
    """The bench process lost more ticks to stalls of its own than this machine is allowed to cost it."""
    return lost > max(OWN_LOSS_LIMIT * ticks_run, OWN_LOSS_MIN_TICKS)


def disturbed(timing: dict, rig: dict | None = None) -> bool:
    """The machine, not the code, decided this run: heavy steal, or either process (bench or rig) not scheduled."""
    worst = timing["lateness_max_us"]
    rig_gap = (rig or {}).get("worst_gap_ms")
    return (timing["cpu_steal_s"] >= STEAL_LIMIT_S or (worst is not None and worst >= STALL_LIMIT_US)
            or rig_gap is None or rig_gap >= RIG_GAP_LIMIT_MS)


@pytest.mark.slow
@pytest.mark.realtime
def test_realtime_test_over_slcan_against_the_rig_process(tmp_path: Path) -> None:
    """`edc-bench test --realtime` starts `edc-bench rig` and drives it over slcan/TCP at 1 kHz.

    This shared 2-core VM stalls processes for milliseconds at times (CPU steal, slow
    wake-ups); the default acceptance aborts after 5 replies missing in a row. This test
    checks the real-time path, so its variant tolerates 50 in a row; the record still
    counts every missed reply and overrun. Up to three attempts, each reported. A run that
    does not complete although the machine ran it undisturbed (little CPU steal, no tick
    10 ms late) fails the test; if every attempt was disturbed, the test is skipped with
    the measured figures.
    """
    source = (REPO / "configs" / "p-edc-default.toml").read_text()
    variant_file = tmp_path / "rt.toml"
    variant_file.write_text(source.replace('name = "p-edc-default"', 'name = "rt-test"')
                            + "\n[acceptance]\nmax_missed_replies_in_row = 50\nmax_overrun_fraction = 0.2\n"
                            "max_missed_reply_fraction = 0.2\n")
    attempts = []
    for attempt in range(3):
        proc = edc_bench("test", "--realtime", "--variant", str(variant_file), "--valve", "worn",
                         "--duration-s", "12", "--json", "--no-figure", "--out", "rec", cwd=tmp_path)
        assert proc.returncode in (11, 12), proc.stderr  # a worn valve: FAIL, or INVALID if disturbed
        summary = json.loads(proc.stdout)
        timing = summary["timing"]
        doc = json.loads(Path(tmp_path / summary["record_dir"], "record.json").read_text())
        rig = doc["simulation"]["rig_process"]
        attempts.append({**timing, "rig_worst_gap_ms": rig.get("worst_gap_ms")})
        print(f"attempt {attempt + 1}: {summary['verdict']} {summary['reasons']} timing {timing}, rig {rig}")
        # every run, complete or not, leaves its timing statistics in the record and the rig safe
        assert summary["clock"] == "real-time"
        for key in ("lateness_p50_us", "lateness_p99_us", "lateness_max_us", "ticks_late", "missed_replies",
                    "cpu_steal_s"):
            assert key in timing
        assert doc["timing"] == timing
        assert doc["loop"]["safe_confirmed"] is True
        assert doc["firmware_version"] == "1.0"
        if doc["loop"]["ticks_run"] == 12_000 and not doc["loop"]["abort_reason"]:
            break  # complete (ticks lost to host stalls are gaps in a complete run, not an end)
        if not disturbed(timing, rig):
            pytest.fail(f"real-time test did not complete on an undisturbed machine: {summary['reasons']} {timing} "
                        f"rig {rig}")
    else:
        pytest.skip("every attempt was disturbed by this machine: " + "; ".join(
            f"{t['ticks']} ticks, steal {t['cpu_steal_s']:.2f} s, worst tick {t['lateness_max_us'] / 1e3:.1f} ms late, "
            f"rig's worst serve gap {t['rig_worst_gap_ms']} ms"
            for t in attempts))
    assert timing["missed_replies"] < 1200
    # identification in real time: the rig process runs the worn preset, whose truth is known here
    variant = load_variant()
    truth = feedforward_truth(plant_parameters(variant, parse_valve_spec("worn", variant)))
    assert abs(summary["features"]["af"] / truth.af - 1) < 0.08
    assert abs(summary["features"]["a1"] / truth.a1 - 1) < 0.20


def _attempts(run, what: str, tries: int = 3):
    """Run ``run()`` until an attempt completes or is undisturbed, and return whether it completed; skip if
    every attempt was disturbed and none completed.

    ``run`` returns (completed, timing, rig, description, machine): ``machine`` names what this machine did to
    the run beyond :func:`disturbed`'s checks ("" if nothing). A completed attempt passes, disturbed or not (the
    disturbance excuses a failure, it does not spoil a success; ``run`` has checked the completed run's figures);
    an undisturbed attempt that did not complete fails; only when every attempt was disturbed and failed is the
    test skipped, with every attempt's figures.
    """
    seen = []
    for attempt in range(tries):
        completed, timing, rig, description, machine = run()
        print(f"{what}, attempt {attempt + 1}: {description}; timing {timing}; rig {rig}; machine: {machine or '-'}")
        seen.append(f"{description}: steal {timing['cpu_steal_s']:.2f} s, worst tick "
                    f"{(timing['lateness_max_us'] or 0) / 1e3:.1f} ms late, rig's worst serve gap "
                    f"{(rig or {}).get('worst_gap_ms')} ms {machine}")
        if completed or (not disturbed(timing, rig) and not machine):
            return completed
    pytest.skip(f"{what}: every attempt was disturbed by this machine: " + "; ".join(seen))


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
            assert loop["ticks_run"] == round(stop["time_s"] * 1000) and loop["safe_confirmed"]
            assert stop["reason"] == "verdict certain" or loop["ticks_run"] == 30_000
            assert max(map(int, loop["reply_age_ticks"])) >= 2  # the adapter's latency was there
        rig = doc["simulation"]["rig_process"]
        # the rig process not serving for as many ticks as the missed-reply limit allows in a row can end the
        # test by itself; that is the machine, not the bench
        machine = " ".join(filter(None, [
            f"the machine lost {loop['ticks_lost']} ticks to {loop['gaps']} stalls"
            if lost_too_many(loop["ticks_lost"], loop["ticks_run"]) else "",
            f"rig process did not serve for {rig.get('worst_gap_ms')} ms"
            if (rig.get("worst_gap_ms") or 0) >= LINK_GAP_LIMIT_MS else ""]))
        return completed, summary["timing"], rig, description, machine

    assert _attempts(run, "USB adapter, real time"), "an undisturbed real-time run through usb-fs did not PASS"


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
            assert result.stop["reason"] == "full length"
            assert outcome.ticks_run == 15_000 and clock.stalls >= 12
            assert outcome.gaps >= clock.stalls  # every injected stall shows as a gap (the machine may add some)
            assert 4 * clock.stalls <= outcome.ticks_lost
        # ticks the machine lost by itself, beyond the injected stalls (each costs 5 ticks, 6 with the wake-up),
        # spend the overrun budget the injected ones are checked against
        own_lost = outcome.ticks_lost - 6 * clock.stalls
        machine = " ".join(filter(None, [
            f"the machine lost {own_lost} ticks by itself" if lost_too_many(own_lost, outcome.ticks_run) else "",
            f"rig process did not serve for {status.get('worst_gap_ms')} ms"
            if (status.get("worst_gap_ms") or 0) >= LINK_GAP_LIMIT_MS else ""]))
        return completed, result.timing, status, description, machine

    assert _attempts(run, "5 ms host stalls"), "an undisturbed real-time run with 5 ms stalls was not a valid PASS"


@pytest.mark.slow
@pytest.mark.realtime
def test_following_check_stations_priority_advice_gives_valid_tests(tmp_path: Path) -> None:
    """check-station advises 'chrt -f 50 edc-bench test ...'; followed with --realtime and no bus (the bench starts
    its own rig process), the tests must be valid, with the shipped acceptance. Before the rig process was put
    above the bench and stopped spinning under a real-time policy, 3 of 3 such tests aborted: "6 replies missing
    in a row: the rig stopped answering" (the rig inherited the bench's SCHED_FIFO 50 and spun against it)."""
    import shutil
    import subprocess
    import sys

    from edc_bench.station import judge, system_facts

    facts = system_facts()
    _, _, advice = judge(0.001, __import__("numpy").zeros(10), 0.0, 0.01, {**facts, "realtime_scheduling_now": False},
                         [])
    if not facts.get("realtime_priority_allowed") or shutil.which("chrt") is None:
        pytest.skip("real-time priority is not permitted to this user here (or chrt is missing): the advice is "
                    "the administrator's, not testable")
    assert any("chrt -f 50 edc-bench test" in line for line in advice), advice
    outcomes = []
    for attempt in range(3):
        proc = subprocess.run(["chrt", "-f", "50", sys.executable, "-m", "edc_bench", "test", "--realtime",
                               "--valve", "worn", "--duration-s", "12", "--json", "--no-figure", "--no-history",
                               "--out", "rec"], capture_output=True, text=True, cwd=tmp_path, timeout=300)
        summary = json.loads(proc.stdout)
        doc = json.loads(Path(tmp_path / summary["record_dir"], "record.json").read_text())
        rig = doc["simulation"]["rig_process"]
        outcomes.append((summary["verdict"], summary["reasons"][:2], summary["timing"], rig))
        print(f"attempt {attempt + 1}: {summary['verdict']} {summary['reasons'][:2]} timing {summary['timing']}, "
              f"rig {rig}")
        if summary["verdict"] == "FAIL":
            assert proc.returncode == 11
            return  # valid: a worn valve judged FAIL under the advised priority
        if not disturbed(summary["timing"], rig):
            pytest.fail(f"following check-station's advice gave an invalid test on an undisturbed machine: "
                        f"{summary['reasons']} timing {summary['timing']} rig {rig}")
    pytest.skip(f"every attempt was disturbed by the machine: {outcomes}")
