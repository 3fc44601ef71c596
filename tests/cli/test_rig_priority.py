"""``edc-bench rig`` raises itself one above the bench's real-time priority where the PC permits, and says which it
runs at (the tester's finding: the rig process ran at normal priority while the bench raised its own, and the
two-terminal example ended INVALID 4 of 4 on a busy PC). Nothing here is timed: the rig's first lines are read,
then it is stopped."""

from __future__ import annotations

import shutil
import signal
import subprocess
import sys

import pytest

from edc_bench.runtime.priority import BENCH_PRIORITY, realtime_permitted


def _first_lines(refused: bool = False) -> tuple[list[str], str]:
    command = [sys.executable, "-m", "edc_bench", "rig", "--listen", "127.0.0.1:0"]
    if refused:  # a login without a real-time budget, as a shop's technician account is (root: CAP_SYS_NICE dropped)
        command = ["setpriv", "--bounding-set", "-sys_nice", "prlimit", "--rtprio=0", "--", *command]
    rig = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    assert rig.stdout is not None
    lines = [rig.stdout.readline() for _ in range(2)]
    rig.send_signal(signal.SIGTERM)
    _, err = rig.communicate(timeout=60)  # a hang guard: it stops at once
    return [line.strip() for line in lines], err


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="real-time scheduling is Linux's here")
def test_the_rig_says_the_priority_it_serves_at() -> None:
    lines, err = _first_lines()
    assert lines[0].startswith("rig: variant p-edc-default") and "serving slcan at socket://127.0.0.1:" in lines[0]
    if realtime_permitted():
        assert lines[1] == f"rig: scheduling real-time (SCHED_FIFO {BENCH_PRIORITY + 1}, raised by the bench)"
    else:
        assert lines[1].startswith("rig: scheduling normal (") and "a bench on this PC may find this rig late" in err


@pytest.mark.skipif(not sys.platform.startswith("linux") or not (shutil.which("setpriv") and shutil.which("prlimit")),
                    reason="needs Linux's setpriv and prlimit (util-linux) to run the rig as a login without rtprio")
def test_a_rig_the_pc_will_not_raise_says_so_and_what_to_allow() -> None:
    lines, err = _first_lines(refused=True)
    assert lines[1].startswith("rig: scheduling normal (not permitted")
    assert "the administrator runs, once" in err
