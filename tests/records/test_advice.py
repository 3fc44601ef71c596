"""The technician's line: what to do after a test, from typed values, the same in the output, the record and the
report."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from helpers import edc_bench

from edc_bench.engine.outcome import AbortKind
from edc_bench.engine.problems import Problem
from edc_bench.engine.outcome import CHECK_BUS, CHECK_PC, CHECK_PUMP, CHECK_RIG, what_to_check
from edc_bench.records.advice import (
    CUSTOMER_WORDS,
    SEIZED,
    Action,
    Advice,
    Area,
    Cause,
    advice,
    escalation,
    invalid_area,
    invalid_cause,
)
from edc_bench.verdict.verdicts import Verdict


@pytest.mark.parametrize(("verdict", "problems", "kind", "action", "words"), [
    (Verdict.PASS, Problem.NONE, None, Action.REFIT, "reusable: refit the valve"),
    (Verdict.FAIL, Problem.NONE, None, Action.REPLACE, "worn: replace the valve"),
    (Verdict.FAIL, Problem.COIL_OUT_OF_SPEC, None, Action.REPLACE, "coil out of spec: replace the valve"),
    (Verdict.MARGINAL, Problem.NONE, None, Action.RETEST, "near the limit: retest"),
    (Verdict.INVALID, Problem.ABORTED, AbortKind.SILENCE, Action.CHECK, "not judged: check the rig"),
    (Verdict.INVALID, Problem.ABORTED, AbortKind.OFF_REFERENCE, Action.CHECK, "not judged: check the mounting"),
    (Verdict.INVALID, Problem.ABORTED, AbortKind.FOREIGN_COMMAND, Action.CHECK, "not judged: check the bus"),
    (Verdict.INVALID, Problem.TIMING, None, Action.CHECK, "not judged: check the PC"),
    (Verdict.INVALID, Problem.MODEL_DOES_NOT_FIT, None, Action.CHECK, "not judged: check the pump's part number"),
    (Verdict.INVALID, Problem.NOT_CALIBRATED, None, Action.CALIBRATE, "not judged: this pump type has no"),
    (Verdict.INVALID, Problem.DRIFTING | Problem.TIMING, None, Action.CHECK, "not judged: check the PC"),
])
def test_each_outcome_says_what_to_do(verdict: Verdict, problems: Problem, kind: AbortKind | None, action: Action,
                                      words: str) -> None:
    said = advice(verdict, problems, kind)
    assert said.action == action and said.words.startswith(words), said


@pytest.mark.parametrize(("valve", "code", "words"), [("worn", 11, "worn valve or a dragging rack: check by hand that "
                                                                   "the rack moves freely, then replace the valve"),
                                                      ("new", 0, "reusable: refit the valve")])
def test_the_test_command_and_its_record_say_it(tmp_path: Path, valve: str, code: int, words: str) -> None:
    from edc_bench.records.reader import load_record

    if valve == "worn":  # the plain output's first line
        plain = edc_bench("test", "--valve", valve, "--no-figure", "--plain", "--no-history", "--out", "rec",
                          cwd=tmp_path)
        assert plain.returncode == code, plain.stderr
        first = plain.stdout.splitlines()[0]
        assert first == f"verdict: FAIL, {words}", first
        return
    as_json = edc_bench("test", "--valve", valve, "--no-figure", "--json", "--no-history", "--out", "rec",
                        cwd=tmp_path)
    assert as_json.returncode == code, as_json.stderr
    summary = json.loads(as_json.stdout)
    assert summary["advice"] == {"action": "refit", "words": words}
    assert load_record(tmp_path / summary["record_dir"]).advice.words == words  # the report's line is the same


def test_an_invalid_test_says_what_to_check(tmp_path: Path) -> None:
    # a rig that never answers: INVALID, with the rig to check
    proc = edc_bench("test", "--interface", "virtual", "--channel", "edc-bench-nobody-here", "--plain",
                     "--no-history", "--out", "rec", "--valve-id", "V-1", cwd=tmp_path)
    assert proc.returncode == 12, proc.stderr
    assert proc.stdout.splitlines()[0].startswith("verdict: INVALID, not judged: check the rig"), proc.stdout


@pytest.mark.parametrize(("problems", "abort_kind", "cause"), [
    (Problem.ABORTED, AbortKind.OFF_REFERENCE, Cause.VALVE),  # the rack does not follow: stuck or far worn
    (Problem.MODEL_DOES_NOT_FIT, None, Cause.VALVE),
    (Problem.DRIFTING, None, Cause.VALVE),
    (Problem.POORLY_CONDITIONED, None, Cause.VALVE),
    (Problem.ABORTED, AbortKind.SILENCE, Cause.BENCH),
    (Problem.ABORTED, AbortKind.BUS_ERROR, Cause.BENCH),
    (Problem.TIMING, None, Cause.BENCH),
    (Problem.REPLIES_MISSING | Problem.DRIFTING, None, Cause.BENCH),  # the bench's problem explains the rest
    (Problem.ABORTED, AbortKind.RIG_FAULT, Cause.EITHER),  # an over-current: the coil or the rig
    (Problem.ABORTED, AbortKind.INTERRUPTED, Cause.INTERRUPTED),
    (Problem.NOT_CALIBRATED, None, Cause.NOT_SET_UP),
])
def test_an_invalid_test_points_at_the_valve_the_bench_or_either(problems: Problem, abort_kind: AbortKind | None,
                                                                 cause: Cause) -> None:
    assert invalid_cause(problems, abort_kind) is cause
    words = CUSTOMER_WORDS[cause]
    for engineers in ("mm", "ticks", "variant", "polarity", "P(faulty)", "rms"):
        assert engineers not in words, (cause, engineers)


def test_only_a_second_invalid_the_valve_can_cause_both_times_is_escalated() -> None:
    assert escalation(Cause.VALVE, Cause.VALVE) == Advice(Action.REPLACE, SEIZED)
    assert "may be seized: replace it, or escalate to the engineer" in SEIZED
    for first, second in ((None, Cause.VALVE), (Cause.BENCH, Cause.VALVE), (Cause.VALVE, Cause.BENCH),
                          (Cause.EITHER, Cause.VALVE), (Cause.VALVE, Cause.INTERRUPTED)):
        assert escalation(first, second) is None, (first, second)


_FIRST_CHECK = {CHECK_RIG: Area.RIG, CHECK_PUMP: Area.MOUNTING, CHECK_BUS: Area.BUS, CHECK_PC: Area.PC}


@pytest.mark.parametrize("kind", list(AbortKind))
def test_an_aborts_area_is_the_first_thing_its_advice_says_to_check(kind: AbortKind) -> None:
    """#55: the chain ranks INVALID tests by where to look; that is what the technician was told to check first."""
    area = invalid_area(Problem.ABORTED, kind)
    first = next((a for check, a in _FIRST_CHECK.items() if what_to_check(kind).startswith(check)), None)
    expected = first or (Area.INTERRUPTED if kind is AbortKind.INTERRUPTED else Area.OTHER)
    assert area is expected, (kind, what_to_check(kind))


@pytest.mark.parametrize(("problems", "area"), [
    (Problem.NOT_CALIBRATED, Area.CALIBRATION), (Problem.PC_STALLED | Problem.ABORTED, Area.PC),
    (Problem.TIMING, Area.PC), (Problem.REPLIES_MISSING, Area.BUS), (Problem.NOT_IDENTIFIED, Area.RIG),
    (Problem.MODEL_DOES_NOT_FIT, Area.MOUNTING), (Problem.TOO_FEW_PERIODS, Area.OTHER),
])
def test_a_trust_problems_area_follows_the_advice(problems: Problem, area: Area) -> None:
    assert invalid_area(problems, AbortKind.SILENCE if Problem.ABORTED in problems else None) is area


def test_the_history_indexes_where_an_invalid_test_points(tmp_path: Path) -> None:
    db = f"sqlite:///{tmp_path / 'h.sqlite'}"
    proc = edc_bench("test", "--interface", "virtual", "--channel", "edc-bench-nobody-here", "--plain",
                     "--db", db, "--out", "rec", "--valve-id", "V-1", cwd=tmp_path)
    assert proc.returncode == 12, proc.stderr
    listed = edc_bench("history", "--db", db, "--summary", "--json", cwd=tmp_path)
    assert json.loads(listed.stdout)["invalid_areas"] == [["rig", 1]], listed.stdout
