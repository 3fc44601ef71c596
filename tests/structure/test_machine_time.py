"""The default suite judges no machine's speed: every module of it that reads a clock, sleeps, opens a socket or
waits with a timeout is listed in ``tests/machine_time.py`` with how it stays independent of the machine (simulated
time, lockstep, a hang guard, or a skip on a measured disturbance), and docs/testing.md prints that list."""

from __future__ import annotations

import ast
from pathlib import Path

from helpers import REPO
from machine_time import MODULES, ONLY_IN_SLOW_TESTS, READS_A_CLOCK, Kind

THIS = {"tests/machine_time.py", "tests/structure/test_machine_time.py"}


def _out_of_the_default_suite(source: str) -> bool:
    """Whether the module as a whole is marked slow or realtime (its ``pytestmark``)."""
    for node in ast.parse(source).body:
        if isinstance(node, ast.Assign) and any(isinstance(t, ast.Name) and t.id == "pytestmark"
                                                for t in node.targets):
            marks = ast.get_source_segment(source, node.value) or ""
            if "pytest.mark.slow" in marks or "pytest.mark.realtime" in marks:
                return True
    return False


def _reading_a_clock() -> set[str]:
    found = set()
    for path in sorted((REPO / "tests").rglob("*.py")):
        name = path.relative_to(REPO).as_posix()
        source = path.read_text(encoding="utf-8")
        if name in THIS or not READS_A_CLOCK.search(source) or _out_of_the_default_suite(source):
            continue
        found.add(name)
    return found


def _default_tests_reading_a_clock(source: str) -> list[str]:
    """The module's test functions in the default suite (not marked slow or realtime) whose own body reads a
    clock."""
    found = []
    for node in ast.walk(ast.parse(source)):
        if not isinstance(node, ast.FunctionDef) or not node.name.startswith("test_"):
            continue
        marks = " ".join(ast.get_source_segment(source, d) or "" for d in node.decorator_list)
        if "slow" in marks or "realtime" in marks:
            continue
        if READS_A_CLOCK.search(ast.get_source_segment(source, node) or ""):
            found.append(node.name)
    return found


def test_every_module_of_the_default_suite_that_reads_a_clock_says_why_no_machine_can_fail_it() -> None:
    found = _reading_a_clock()
    unlisted = sorted(found - set(MODULES) - set(ONLY_IN_SLOW_TESTS))
    assert not unlisted, (f"{unlisted} read a clock, sleep, open a socket or wait with a timeout: list each in "
                          "tests/machine_time.py with how it stays independent of the machine's speed (or mark it "
                          "realtime: .ci/run runs those alone)")
    stale = sorted((set(MODULES) | set(ONLY_IN_SLOW_TESTS)) - found)
    assert not stale, f"{stale} are listed in tests/machine_time.py but read no clock in the default suite now"
    assert not set(MODULES) & set(ONLY_IN_SLOW_TESTS)


def test_a_module_said_to_read_clocks_only_in_slow_tests_does_so() -> None:
    for name in ONLY_IN_SLOW_TESTS:
        reading = _default_tests_reading_a_clock((REPO / name).read_text(encoding="utf-8"))
        assert not reading, f"{name}: {reading} read a clock in the default suite: list the module in MODULES"


def test_each_listed_module_says_its_kinds_and_why() -> None:
    for name, (kinds, why) in MODULES.items():
        assert kinds and all(isinstance(k, Kind) for k in kinds), name
        assert len(why) > 20, name


def test_the_search_finds_a_clock_read_in_any_of_its_forms() -> None:
    for text in ("time.monotonic()", "time.perf_counter_ns()", "time.sleep(0.1)", "RealTimeClock()",
                 "import socket", "proc.wait(timeout=5)", "os.getloadavg()", "thread.join(30)",
                 "typed.wait(30)", "await asyncio.sleep(0.1)"):
        assert READS_A_CLOCK.search(text), text
    assert not READS_A_CLOCK.search("simulated_time_s = clock.now_s()")


def test_a_module_marked_realtime_or_slow_is_out_of_the_default_suite() -> None:
    assert _out_of_the_default_suite("import pytest\npytestmark = pytest.mark.realtime\n")
    assert _out_of_the_default_suite("import pytest\npytestmark = [NEEDS_TMUX,\n    pytest.mark.slow]\n")
    assert not _out_of_the_default_suite("import pytest\npytestmark = pytest.mark.skipif(True, reason='x')\n")
