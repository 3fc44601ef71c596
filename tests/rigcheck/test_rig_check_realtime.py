"""edc-bench rig-check in real time against the rig process (slcan over loopback TCP), as a rig builder runs it.

A real-time check that fails only because this shared machine did not run one of the two processes on time
(CPU steal, the bench woken late, the rig process not serving) is skipped with its figures; a NO-GO on an
undisturbed run fails.
"""

from __future__ import annotations

import pytest

from edc_bench.config import load_variant
from edc_bench.protocol import default_icd
from edc_bench.rigcheck import run_rig_check
from edc_bench.runtime.bus import ClosingBus, open_bus
from edc_bench.runtime.clock import RealTimeClock, cpu_steal_s
from edc_bench.sim.process import rig_process
from firmware_proto.c_firmware import c_firmware_available, library_path

# slow: CI runs these alone (-n 0), where a real-time check measures the rig and not the other tests' load
pytestmark = [pytest.mark.realtime, pytest.mark.slow]

STEAL_LIMIT_S = 0.15
LATE_LIMIT_MS = 5.0  # the bench side woken this late: a timing check cannot tell the rig from the PC
RIG_GAP_LIMIT_MS = 5.0  # the rig process did not serve for this long


def _check(adapter: str = "none", breaks: tuple[str, ...] = (), firmware: str = "python"):
    status: dict[str, float] = {}
    steal_before = cpu_steal_s()
    extra = [a for b in breaks for a in ("--break", b)] + ["--firmware", firmware]
    with rig_process(None, "new", 3, adapter, status, extra=extra) as channel:
        with ClosingBus(open_bus({"interface": "slcan", "channel": channel}, default_icd().bitrate)) as bus:
            report = run_rig_check(bus, RealTimeClock(), load_variant(), where=channel, commands=500)
    steal = cpu_steal_s() - steal_before
    disturbed = (steal >= STEAL_LIMIT_S or report.worst_late_ms >= LATE_LIMIT_MS
                 or status.get("worst_gap_ms", float("inf")) >= RIG_GAP_LIMIT_MS)
    figures = (f"steal {steal:.2f} s, bench woken up to {report.worst_late_ms:.1f} ms late, rig's worst serve gap "
               f"{status.get('worst_gap_ms')} ms; failed: {[(r.key, r.measured) for r in report.failed]}")
    print(figures)
    return report, disturbed, figures


@pytest.mark.parametrize(("adapter", "firmware"), [("none", "python"), ("usb-fs", "python"), ("none", "c")])
def test_the_rig_process_is_go_in_real_time(adapter: str, firmware: str) -> None:
    if firmware == "c" and not c_firmware_available():
        pytest.skip(f"the C firmware is not built ({library_path()}): this machine has no make or cc")
    report, disturbed, figures = _check(adapter, firmware=firmware)
    if not report.go and disturbed:
        pytest.skip(f"the machine got in the way: {figures}")
    assert report.go, figures


def test_a_rig_process_with_a_slow_watchdog_is_no_go_in_real_time() -> None:
    report, disturbed, figures = _check(breaks=("slow-watchdog",))
    failed = {r.key for r in report.failed}
    if failed != {"watchdog"} and disturbed:
        pytest.skip(f"the machine got in the way: {figures}")
    assert failed == {"watchdog"}, figures
