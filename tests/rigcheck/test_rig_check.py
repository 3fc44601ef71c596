"""edc-bench rig-check: GO on a rig that keeps ICD v1, NO-GO naming the one rule a broken rig breaks."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from edc_bench.cli import main
from edc_bench.config import load_variant
from edc_bench.physics.valve import parse_valve_spec
from edc_bench.rigcheck import RigCheckReport, run_rig_check
from edc_bench.rigcheck.report import verdict_line
from edc_bench.runtime.bus import ClosingBus
from edc_bench.runtime.clock import SimulatedClock
from edc_bench.sim.adapter import parse_adapter
from edc_bench.sim.broken_rigs import IcdBreak
from edc_bench.sim.inprocess import InProcessRig
from edc_bench.sim.lockstep_bus import lockstep_pair
from edc_bench.sim.rig import RigOptions, SimulatedRig

EVERY_CHECK = {"heartbeat", "supply", "answered", "bad_crc", "wrong_length", "undefined_mode", "repeated_counter",
               "every_command", "counter_echo", "reply_latency", "watchdog", "watchdog_latch", "safe",
               "samples_first", "trip_flags"}

#: The checks each broken rule fails: that one, nothing else.
FAILS = {
    IcdBreak.ANSWERS_BAD_CRC: {"bad_crc"},
    IcdBreak.WRONG_COUNTER_ECHO: {"counter_echo"},
    IcdBreak.SLOW_WATCHDOG: {"watchdog"},
    IcdBreak.NO_WATCHDOG: {"watchdog"},
    IcdBreak.NO_HEARTBEAT: {"heartbeat"},
    IcdBreak.SLOW_HEARTBEAT: {"heartbeat"},
    IcdBreak.DRIVES_AFTER_SAFE: {"safe"},
    IcdBreak.SAMPLES_AFTER_DRIVE: {"samples_first"},
}


def check_simulated(breaks: frozenset[IcdBreak] = frozenset(), adapter: str | None = None,
                    commands: int = 400, provoke_trips: bool = False) -> tuple[RigCheckReport, SimulatedRig]:
    variant = load_variant()
    rig = SimulatedRig(variant, parse_valve_spec("new", variant), options=RigOptions(breaks=breaks))
    bench_end, rig_end = lockstep_pair()
    with ClosingBus(bench_end) as bus, ClosingBus(rig_end):
        link = InProcessRig(rig_end, rig, adapter=parse_adapter(adapter) if adapter else None)
        return run_rig_check(bus, SimulatedClock(link), variant, commands=commands,
                             provoke_trips=provoke_trips), rig


@pytest.mark.parametrize("adapter", [None, "usb-fs"])
def test_a_rig_that_keeps_the_icd_is_go_with_every_figure(adapter: str | None) -> None:
    report, rig = check_simulated(adapter=adapter)
    assert report.go, [(r.key, r.measured) for r in report.failed]
    assert {r.key for r in report.results} == EVERY_CHECK
    ran = {r.key for r in report.results if r.passed is not None}
    assert ran == EVERY_CHECK - {"trip_flags"}  # provoking trips is left out on purpose, and said so
    figures = {r.key: r.figures for r in report.results}
    assert figures["heartbeat"]["median_ms"] == pytest.approx(100.0, abs=1.0)
    assert figures["every_command"]["replies"] == 400
    # announced at once: the watchdog's 20 ms, the heartbeat's way back through the adapter, the 0.5 ms polling
    assert 20.0 <= figures["watchdog"]["trip_ms"] <= (24.0 if adapter else 21.0)
    if adapter:  # the USB model's round trip: 1.5-3.5 ms
        assert 1.0 <= figures["reply_latency"]["p50_ms"] <= 3.5
    # left in SAFE: READY, the amplifier at 0 V
    assert rig.firmware.state.name == "READY" and rig.plant.drive_v == 0.0


@pytest.mark.parametrize("rule", list(IcdBreak), ids=lambda rule: rule.value)
def test_a_rig_that_breaks_one_rule_is_no_go_naming_that_rule_alone(rule: IcdBreak) -> None:
    report, _ = check_simulated(frozenset({rule}))
    assert not report.go
    assert {r.key for r in report.failed} == FAILS[rule]


@pytest.mark.slow
@pytest.mark.parametrize("rule", list(IcdBreak), ids=lambda rule: rule.value)
def test_through_a_usb_adapter_too(rule: IcdBreak) -> None:
    report, _ = check_simulated(frozenset({rule}), adapter="usb-fs")
    assert {r.key for r in report.failed} == FAILS[rule]


def test_the_command_writes_json_and_a_one_page_pdf_and_exits_0_for_go(tmp_path: Path,
                                                                      capsys: pytest.CaptureFixture[str]) -> None:
    code = main(["rig-check", "--commands", "200", "--out", str(tmp_path / "go")])
    out = capsys.readouterr().out
    assert code == 0
    assert "GO  the rig kept every ICD rule checked" in out
    data = json.loads((tmp_path / "go" / "rig-check.json").read_text())
    assert data["verdict"] == "GO" and len(data["checks"]) == len(EVERY_CHECK)
    pdf = (tmp_path / "go" / "rig-check.pdf").read_bytes()
    assert pdf.startswith(b"%PDF") and len(re.findall(rb"/Type\s*/Page\b(?!s)", pdf)) == 1


def test_a_broken_rig_exits_15_and_names_the_rule(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code = main(["rig-check", "--commands", "200", "--break", "no-watchdog", "--json", "--out", str(tmp_path)])
    data = json.loads(capsys.readouterr().out)
    assert code == 15
    assert data["verdict"] == "NO-GO"
    assert [c["key"] for c in data["checks"] if c["result"] == "FAIL"] == ["watchdog"]


@pytest.mark.parametrize(("argv", "says"), [
    (["--break", "late-replies"], "no such ICD break 'late-replies': one of answers-bad-crc"),
    (["--break", "no-watchdog", "--interface", "virtual", "--channel", "x"], "apply to the simulated rig only"),
    (["--commands", "5"], "give a whole number of commands from 100 to 100000"),
])
def test_bad_input_is_one_line(argv: list[str], says: str, tmp_path: Path,
                               capsys: pytest.CaptureFixture[str]) -> None:
    try:
        code = main(["rig-check", "--out", str(tmp_path), *argv])
    except SystemExit as exc:  # argparse's own refusal
        code = exc.code
    err = capsys.readouterr().err
    assert code == 2
    assert says in err and "Traceback" not in err


def test_a_bus_where_nothing_answers_says_so_and_leaves_nothing_running() -> None:
    variant = load_variant()
    bench_end, nobody = lockstep_pair()
    with ClosingBus(bench_end) as bus, ClosingBus(nobody):
        report = run_rig_check(bus, SimulatedClock(), variant, commands=100)
        # what the check sent last was SAFE: a rig that came alive meanwhile would switch its amplifier off
        last = None
        while (msg := nobody.recv()) is not None:
            last = msg
    assert last is not None and last.data[2] == 0  # byte 2: Mode, 0 SAFE
    assert not report.go and report.frames_received == 0
    assert "no frame came from the rig" in verdict_line(report)


def test_provoked_trips_are_checked_only_when_asked_and_leave_the_rig_safe() -> None:
    report, rig = check_simulated(provoke_trips=True)
    results = {r.key: r for r in report.results}
    assert "trip_flags" not in results
    for key, code in (("over_current", "OVER_CURRENT"), ("travel_limit", "TRAVEL_LIMIT")):
        assert results[key].passed, results[key].measured
        assert results[key].figures["fault_codes"][0] == code
    assert report.go
    assert rig.firmware.state.name == "READY" and rig.plant.drive_v == 0.0
