"""`edc-bench session` in a real terminal (tmux), typed at as a technician would: the screen read back with
capture-pane. Skips where tmux is not installed (.ci/run installs it)."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest
from tmux_terminal import NEEDS_TMUX, Terminal, set_up_station, terminal_env

pytestmark = NEEDS_TMUX


def _end_shift(term: Terminal) -> str:
    """Ctrl+Q, which asks, then Ctrl+Q again; the screen once the session has exited."""
    term.keys("C-q")
    term.wait_for("End the shift? Press Ctrl+Q again")
    term.keys("C-q")
    return term.wait_for("EXITED")


@pytest.mark.slow  # the default suite's 5 minutes; CI's slow pass runs it
def test_a_technician_works_a_short_shift_in_a_real_terminal(tmp_path: Path) -> None:
    env = terminal_env({"EDC_BENCH_DATA_DIR": str(tmp_path / "data")})
    term = Terminal([sys.executable, "-m", "edc_bench", "session", "--db", f"sqlite:///{tmp_path / 'h.sqlite'}"],
                    tmp_path, env)
    try:
        term.wait_for("Type your NAME")
        term.keys("Anna", "Enter")
        term.wait_for("Type the WORKSHOP's")  # a station new to the session: asked once, after the operator
        term.keys("Diesel Müller GmbH", "Enter", "Hauptstraße 5, 80331 München", "Enter")
        term.wait_for("BENCH's NAME")  # the settings name no station: the name the customer's page prints
        term.keys("Bench 2", "Enter")
        term.wait_for("workshop kept in")
        term.wait_for("operator Anna")
        term.keys("clearance=0.185", "Enter")
        term.wait_for("PUMP SERIAL")
        term.keys("PS-4471", "Enter")
        term.wait_for("Mount the valve")
        term.keys("Enter")
        decided = term.wait_for("NEAR THE LIMIT TWICE: REPLACE THE VALVE")
        assert "FAIL  (MARGINAL, retest MARGINAL)" in decided
        term.keys("new", "Enter")
        term.wait_for("PUMP SERIAL")
        term.keys("PS-4472", "Enter")
        term.wait_for("Mount the valve")
        term.keys("Enter")
        passed = term.wait_for("REUSABLE: REFIT THE VALVE")
        assert "valves 2, tests 3" in passed
        ended = _end_shift(term)
    finally:
        term.close()
    assert "EXITED 0" in ended
    assert "valves: 2 (1 PASS, 1 FAIL); tests: 3; retests: 1" in ended
    assert "shift summary: records/shift-" in ended


@pytest.mark.slow
def test_at_80x24_the_prompts_wrap_and_keys_typed_during_a_test_are_held_back(tmp_path: Path) -> None:
    """#53: at 80 columns the one-line prompt was cut before what to do; keys typed during a test were glued to the
    next valve id."""
    env = terminal_env({"EDC_BENCH_DATA_DIR": str(set_up_station(tmp_path / "data"))})
    term = Terminal([sys.executable, "-m", "edc_bench", "session", "--operator", "Anna", "--db",
                     f"sqlite:///{tmp_path / 'h.sqlite'}"], tmp_path, env, columns=80, rows=24)
    try:
        term.wait_for("VALVE ID")
        term.keys("V-20417", "Enter")
        term.wait_for("PUMP SERIAL")
        term.keys("PS-4471", "Enter")
        mount = term.wait_for("Mount the valve")
        assert "then press Enter to\n test it" in mount  # wrapped, not cut
        term.keys("Enter")
        term.wait_for("keys typed now are not taken")
        term.keys("V-1")  # during the test
        begun = term.wait_for("was begun during the test")
        term.keys("23", "Enter")  # the rest of the scan after the verdict: the line is refused whole
        refused = term.wait_for("is not taken whole")
        ended = _end_shift(term)
    finally:
        term.close()
    assert "'V-1' was begun during the test: Enter refuses it" in begun
    assert "'V-123' was begun while the test ran" in refused and "VALVE ID" in refused
    assert "EXITED 0" in ended and "valves: 1 " in ended


@pytest.mark.slow
@pytest.mark.parametrize(("fault", "words"), [
    (["--rack-fault", "bind"], ("the rack binds at one", "free or repair the rack")),
    (["--sensor-fault", "gain=1.08"], ("rack-travel sensor is out of", "calibrate or replace the")),
    (["--sensor-fault", "kink"], ("sensor reads unevenly over part", "check it over a reference travel")),
])
def test_at_80x24_the_verdict_names_the_part_at_fault(tmp_path: Path, fault: list[str],
                                                       words: tuple[str, str]) -> None:
    """#67: a sound valve in a pump whose rack binds, whose sensor reads long or reads unevenly: the session's verdict
    box names the part and what to do, every word whole at 80x24, and never says replace the valve."""
    env = terminal_env({"EDC_BENCH_DATA_DIR": str(set_up_station(tmp_path / "data"))})
    term = Terminal([sys.executable, "-m", "edc_bench", "session", "--operator", "Anna", *fault,
                     "--db", f"sqlite:///{tmp_path / 'h.sqlite'}"], tmp_path, env, columns=80, rows=24)
    try:
        term.wait_for("VALVE ID")
        term.keys("new", "Enter")  # on the simulated rig a valve id of a preset's name is that valve
        term.wait_for("PUMP SERIAL")
        term.keys("PS-4471", "Enter")
        term.wait_for("Mount the valve")
        term.keys("Enter")
        term.wait_for("INVALID")
        shown = term.wait_for("then retest the valve")
        ended = _end_shift(term)
    finally:
        term.close()
    flat = " ".join(shown.split())
    assert "not judged" in flat and all(w in flat for w in words), shown
    assert "replace the valve" not in flat.lower(), shown
    assert "EXITED 0" in ended
