"""The bench's own real-time priority: raised where the PC permits, restored after, said where refused."""

from __future__ import annotations

import json
import os
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


#: run in a fresh single-threaded Python (a drop in preexec_fn could deadlock a threaded test process): no rtprio
#: limit and, for root, CAP_SYS_NICE out of the bounding set, then exec the code given, which then lacks it
_DROP_THEN_EXEC = """
import ctypes, os, resource, sys
resource.setrlimit(resource.RLIMIT_RTPRIO, (0, 0))
if os.geteuid() == 0 and ctypes.CDLL(None, use_errno=True).prctl(24, 23, 0, 0, 0) != 0:  # PR_CAPBSET_DROP, SYS_NICE
    raise SystemExit("prctl(PR_CAPBSET_DROP) refused")
os.execv(sys.executable, [sys.executable, "-c", sys.argv[1]])
"""


def _refused_child(code: str) -> subprocess.CompletedProcess:
    """``code`` in a Python that may not have real-time priority."""
    env = {**os.environ, "USER": "someone-else"}  # the login named is the process's, not $USER
    return subprocess.run([sys.executable, "-c", _DROP_THEN_EXEC, code], capture_output=True, text=True,
                          timeout=120, env=env)


def test_where_the_os_refuses_the_test_runs_at_normal_priority_and_says_what_the_administrator_runs() -> None:
    proc = _refused_child(
        "import json\n"
        "from edc_bench.runtime.priority import how_to_allow, priority_notice, realtime_now, realtime_permitted,"
        " realtime_priority\n"
        "with realtime_priority() as p: print(json.dumps([p.realtime, p.describe(), realtime_now(),"
        " realtime_permitted(), how_to_allow(), priority_notice(False)]))")
    assert proc.returncode == 0, proc.stderr
    realtime, words, now, permitted, allow, notice = json.loads(proc.stdout)
    assert (realtime, now, permitted) == (False, False, False)
    assert words == "normal (not permitted: the OS refused a real-time priority (edc-bench check-station says " \
                    "what to allow))"  # the record's words: no login in them
    assert allow.startswith("real-time priority is not permitted for the user '") and "someone-else" not in allow
    assert "@edc-bench - rtprio 50" in allow and "/etc/security/limits.d/edc-bench.conf" in allow
    assert "log in again" in allow and "check-station" in allow
    assert notice is not None and notice.endswith(allow)  # a session on a real rig is told, found by trying


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
