"""check-station's judgement and advice; the one-page report; the live panel's rendering."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from edc_bench.bench import run_bench_test, run_simulated_test
from edc_bench.config import load_variant
from edc_bench.physics.valve import parse_valve_spec
from edc_bench.records.record import write_record
from edc_bench.runtime.clock import SimulatedClock
from edc_bench.sim.inprocess import InProcessRig
from edc_bench.sim.lockstep_bus import lockstep_pair
from edc_bench.sim.rig import SimulatedRig
from edc_bench.station import judge
from edc_bench.testing.faults import FaultyBus, Rule

CALM = {"governor": "performance", "on_battery": False, "realtime_scheduling_now": True}


def test_station_go_when_the_loop_keeps_time() -> None:
    late = np.full(10_000, 20e-6)
    verdict, reasons, advice = judge(1e-3, late, 0.0, 0.01, CALM, [])
    assert (verdict, reasons, advice) == ("GO", [], [])


def test_station_no_go_names_the_causes_and_advises() -> None:
    late = np.full(10_000, 20e-6)
    late[::50] = 1.5e-3  # 2 % of ticks overrun
    facts = {"governor": "powersave", "on_battery": True, "realtime_scheduling_now": False,
             "realtime_priority_allowed": False}
    verdict, reasons, advice = judge(1e-3, late, 0.8, 0.01, facts, [("firefox", 0.9)])
    assert verdict == "NO-GO"
    assert any("p99.9 lateness 1500 us" in r for r in reasons)
    assert any("200 of 10000 ticks overran" in r for r in reasons)
    text = " ".join(advice)
    for expected in ("virtual machine", "firefox (90% of a CPU)", "'performance'", "battery", "limits.conf"):
        assert expected in text


def test_check_station_command() -> None:
    cmd = [sys.executable, "-m", "edc_bench", "check-station"]
    proc = subprocess.run([*cmd, "--duration-s", "0.5", "--json"], capture_output=True, text=True, timeout=120)
    assert proc.returncode in (0, 14), proc.stderr
    out = json.loads(proc.stdout)
    assert out["verdict"] in ("GO", "NO-GO") and out["ticks"] == 500
    assert set(out["lateness_us"]) == {"p50", "p99", "p99.9", "max"}
    assert (proc.returncode == 0) == (out["verdict"] == "GO")
    bad = subprocess.run([*cmd, "--duration-s", "0"], capture_output=True, text=True, timeout=60)
    assert bad.returncode == 2 and "--duration-s" in bad.stderr


def _aborted_record(tmp_path: Path) -> Path:
    variant = load_variant()
    rig = SimulatedRig(variant, parse_valve_spec("new", variant), 3)
    bench, rig_bus = lockstep_pair()
    with bench, rig_bus:
        clock = SimulatedClock(InProcessRig(rig_bus, rig))
        result = run_bench_test(FaultyBus(bench, clock.now_s, [Rule("cut", 4.0)]), clock, variant, check_gains=False)
    assert result.verdict == "INVALID"
    return write_record(result, tmp_path / "aborted", figure=False)


@pytest.mark.parametrize("kind", ["fail", "invalid"])
def test_report_is_one_pdf_page_and_a_png(tmp_path: Path, kind: str) -> None:
    if kind == "fail":
        result = run_simulated_test(load_variant(), "worn", 2)
        result.identity = {"pump_serial": "P-9", "station": "bench-1", "operator": "jo"}
        folder = write_record(result, tmp_path, figure=False)
    else:
        folder = _aborted_record(tmp_path)
    proc = subprocess.run([sys.executable, "-m", "edc_bench", "report", str(folder), "--out", str(tmp_path / "r")],
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    pdf = (tmp_path / "r" / "report.pdf").read_bytes()
    assert pdf.startswith(b"%PDF") and pdf.count(b"/Type /Page\n") + pdf.count(b"/Type /Page ") <= 1
    assert b"/Type /Pages" in pdf and b"/Count 1" in pdf
    png = (tmp_path / "r" / "report-page.png").read_bytes()
    assert png[:4] == b"\x89PNG"


def test_report_bad_input(tmp_path: Path) -> None:
    proc = subprocess.run([sys.executable, "-m", "edc_bench", "report", str(tmp_path)], capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 2 and "no record.json" in proc.stderr and "Traceback" not in proc.stderr


def test_live_panel_renders_every_phase() -> None:
    from rich.console import Console

    from edc_bench.ui.live import render_snapshot, verdict_panel
    from edc_bench.ui.snapshot import PHASES, Snapshot

    class FakeLoop:  # what the snapshot reads of a BenchLoop
        def __init__(self, result) -> None:
            self.trace = type("T", (), {"columns": result.trace})()
            self.ticks, self.period_s, self.outcome = len(result.trace["t_s"]), 0.001, result.outcome

    result = run_simulated_test(load_variant(), "new", 1)
    snapshot = Snapshot()
    loop = FakeLoop(result)
    console = Console(record=True, width=120, color_system=None)
    for k, phase in zip(range(0, 30_000, 5000), PHASES, strict=True):
        snapshot.enter(phase)
        snapshot.update(k, loop)
        console.print(render_snapshot(snapshot, "title"))
    last_panel = console.export_text()
    # in the last panel every earlier phase is ticked off and the current one is not
    for phase in PHASES[:-1]:
        assert f"{phase} ✓" in last_panel.split("title")[-1]
    assert f"{PHASES[-1]} ✓" not in last_panel
    console.print(verdict_panel(result, Path("records/x")))
    text = console.export_text()
    assert "PASS" in text and "edc-bench report records/x" in text and "replies missing" in text


def test_live_view_draws_in_a_child_process_and_never_blocks_the_loop(capfd: pytest.CaptureFixture[str]) -> None:
    from edc_bench.ui.live import LiveView

    class FakeLoop:
        def __init__(self) -> None:
            names = ("t_s", "reference_mm", "position_mm", "current_a", "drive_v", "feedforward_v", "feedback_v",
                     "af_hat", "a1_hat", "lateness_s")
            self.trace = type("T", (), {"columns": {n: np.linspace(0.0, 1.0, 3000) for n in names}})()
            self.ticks, self.period_s = 3000, 0.001
            self.outcome = type("O", (), {"overruns": 2, "missed_replies": 3, "bad_replies": 0, "heartbeats": 9})()

    loop = FakeLoop()
    with LiveView("live view test") as view:
        view.phase("soft start")
        for k in range(0, 3000, 100):
            view.tick(k, loop)
        view.phase("identify")
        # a flood of updates while the panel is slow to read: dropped, never waited for
        for _ in range(5000):
            view.tick(2900, loop)
    assert view._proc.returncode == 0
    out = capfd.readouterr().out
    assert "live view test" in out and "identify" in out and "3 replies missing" in out
