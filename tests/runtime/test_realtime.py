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
        for key in ("lateness_p50_us", "lateness_p99_us", "lateness_max_us", "overruns", "missed_replies",
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
