"""The bench's own real-time priority: raised where the PC permits, restored after, said where refused."""

from __future__ import annotations

import json
import os
import resource
import subprocess
import sys

import pytest

from edc_bench.runtime.priority import how_to_allow, realtime_now, realtime_permitted, realtime_priority

pytestmark = pytest.mark.skipif(not hasattr(os, "sched_setscheduler"), reason="Linux scheduling policies")


def test_the_bench_raises_its_thread_for_the_block_and_gives_it_back() -> None:
    if not realtime_permitted() or realtime_now():
        pytest.skip("real-time priority is not permitted here, or the suite already runs under it")
    with realtime_priority() as priority:
        assert realtime_now() and os.sched_getparam(0).sched_priority == 50
        assert priority.realtime and priority.describe() == "real-time (SCHED_FIFO 50, raised by the bench)"
        with realtime_priority() as inner:  # the rig process's test inside the command's raise: the same words
            assert inner is priority
        assert realtime_now()
    assert not realtime_now()


def _refused_child(code: str) -> subprocess.CompletedProcess:
    """``code`` in a Python that may not have real-time priority: no rtprio limit and, run by root, without the
    CAP_SYS_NICE capability (dropped from the bounding set, so the Python it execs lacks it)."""
    def drop() -> None:
        resource.setrlimit(resource.RLIMIT_RTPRIO, (0, 0))
        if os.geteuid() == 0:
            import ctypes

            pr_capbset_drop, cap_sys_nice = 24, 23
            if ctypes.CDLL(None, use_errno=True).prctl(pr_capbset_drop, cap_sys_nice, 0, 0, 0) != 0:
                raise OSError(ctypes.get_errno(), "prctl(PR_CAPBSET_DROP) refused")

    env = {**os.environ, "USER": "someone-else"}  # the login named is the process's, not $USER
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120,
                          preexec_fn=drop, env=env)


def test_where_the_os_refuses_the_test_runs_at_normal_priority_and_says_what_the_administrator_runs() -> None:
    proc = _refused_child(
        "import json; from edc_bench.runtime.priority import realtime_priority, realtime_permitted, realtime_now\n"
        "with realtime_priority() as p: print(json.dumps([p.realtime, p.describe(), realtime_now(),"
        " realtime_permitted()]))")
    assert proc.returncode == 0, proc.stderr
    realtime, words, now, permitted = json.loads(proc.stdout)
    assert (realtime, now, permitted) == (False, False, False)
    assert words.startswith("normal (not permitted: real-time priority is not permitted for the user '")
    assert "someone-else" not in words
    assert "@edc-bench - rtprio 50" in words and "/etc/security/limits.d/edc-bench.conf" in words
    assert "log in again" in words and "check-station" in words


def test_how_to_allow_names_the_user_the_group_and_the_limit() -> None:
    words = how_to_allow("tech1")
    assert "usermod -aG edc-bench tech1" in words and "rtprio 50" in words


def test_a_shift_on_a_real_rig_is_told_once_what_to_allow_when_the_bench_cannot_raise_itself() -> None:
    from edc_bench.runtime.priority import priority_notice

    words = priority_notice(False, permitted=False, realtime=False)
    assert words is not None and words.startswith("tests run at normal priority on this PC")
    assert "rtprio 50" in words
    assert priority_notice(True, permitted=False, realtime=False) is None  # simulated time: no priority needed
    assert priority_notice(False, permitted=True, realtime=False) is None  # the bench raises itself
    assert priority_notice(False, permitted=False, realtime=True) is None  # started under chrt
