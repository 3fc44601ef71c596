"""check-station's judgement and advice, and the command."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np

from edc_bench.runtime.priority import realtime_permitted
from edc_bench.station import judge

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
    verdict, reasons, advice = judge(1e-3, late, 0.8, 0.01, facts, [("firefox", 0.9, 4711)])
    assert verdict == "NO-GO"
    assert any("p99.9 lateness 1500 us" in r for r in reasons)
    assert any("200 of 10000 ticks overran" in r for r in reasons)
    text = " ".join(advice)
    for expected in ("virtual machine", "firefox (pid 4711, 90% of a CPU)", "'performance'", "battery",
                     "/etc/security/limits.d/edc-bench.conf", "rtprio 50"):
        assert expected in text


def test_check_station_command() -> None:
    cmd = [sys.executable, "-m", "edc_bench", "check-station"]
    proc = subprocess.run([*cmd, "--duration-s", "0.5", "--json"], capture_output=True, text=True, timeout=120)
    assert proc.returncode in (0, 14), proc.stderr
    out = json.loads(proc.stdout)
    assert out["verdict"] in ("GO", "NO-GO") and out["ticks"] == 500
    assert set(out["lateness_us"]) == {"p50", "p99", "p99.9", "max"}
    assert (proc.returncode == 0) == (out["verdict"] == "GO")
    # measured at the priority a test runs at: the bench raises its own where the PC permits it
    assert out["system"]["measured_at"].startswith("real-time" if realtime_permitted() else "normal")
    bad = subprocess.run([*cmd, "--duration-s", "0"], capture_output=True, text=True, timeout=60)
    assert bad.returncode == 2 and "--duration-s" in bad.stderr
