"""The one trust rule: its problems as bits, the same function behind the judgement, the early stop and the
batch path, and no code that decides by reading a sentence."""

from __future__ import annotations

import ast
from pathlib import Path

import numpy as np
import pytest

import edc_bench
from edc_bench.config import Variant
from edc_bench.identification import trust
from edc_bench.identification.trust import TRUST_PROBLEMS, Problem, judged_condition_number, trust_problems
from edc_bench.population import batch
from edc_bench.verdict import early_stop, judgement


def test_the_rule_says_each_problem_by_its_bit_vectorised(variant: Variant) -> None:
    acc = variant.acceptance
    enough, few = acc.min_periods, acc.min_periods - 1
    flags = trust_problems(
        acc,
        periods=np.array([enough, few, enough, enough, enough, enough, enough, few]),
        settled=np.array([True, True, False, True, True, True, True, True]),
        misfit=np.array([False, False, False, True, False, False, False, True]),
        condition_number=np.array([10.0, 10.0, 10.0, 10.0, 1e9, np.nan, 10.0, 10.0]),
        aborted=np.array([False, False, False, False, False, False, True, False]))
    assert [Problem(int(f)) for f in flags] == [
        Problem.NONE, Problem.TOO_FEW_PERIODS, Problem.DRIFTING, Problem.MODEL_DOES_NOT_FIT,
        Problem.POORLY_CONDITIONED, Problem.POORLY_CONDITIONED,  # an unknown condition is no good one
        Problem.ABORTED,  # an aborted test is judged on its abort, not on what it identified before it
        Problem.TOO_FEW_PERIODS]  # the model fit is judged only with enough periods


def test_timing_and_missing_replies_count_against_the_ticks_that_ran(variant: Variant) -> None:
    acc = variant.acceptance
    ticks = 10_000
    just_over = int(acc.max_overrun_fraction * ticks) + 1
    few = acc.min_periods - 1
    flags = trust_problems(acc, periods=np.array([acc.min_periods, acc.min_periods, few, acc.min_periods]),
                           settled=np.array([True, True, True, False]), misfit=False, condition_number=10.0,
                           ticks=ticks, ticks_late_or_lost=np.array([0, just_over, just_over, just_over]),
                           missed_replies=np.array([int(acc.max_missed_reply_fraction * ticks) + 1, 0, 0, 0]))
    assert [Problem(int(f)) for f in flags] == [
        Problem.REPLIES_MISSING,
        Problem.NONE,  # #53: the stalls cost the rows they touched (left out of the fit), not the test
        Problem.TOO_FEW_PERIODS | Problem.TIMING,  # what remained did not decide: the PC is named
        Problem.DRIFTING | Problem.TIMING]
    aborted = trust_problems(acc, periods=acc.min_periods, settled=True, misfit=False, condition_number=10.0,
                             aborted=True, ticks=ticks, ticks_late_or_lost=just_over)
    assert Problem(int(aborted)) == Problem.ABORTED | Problem.TIMING
    # a misfit of what remained, after many ticks lost: the PC is named beside it (not the valve alone)
    misfit = trust_problems(acc, periods=acc.min_periods, settled=True, misfit=True, condition_number=10.0,
                            ticks=ticks, ticks_late_or_lost=just_over)
    assert Problem(int(misfit)) == Problem.MODEL_DOES_NOT_FIT | Problem.TIMING
    # a record of schema 8 and before was decided by the old rule, and is checked by it
    old_rule = trust_problems(acc, periods=acc.min_periods, settled=True, misfit=False, condition_number=10.0,
                              ticks=ticks, ticks_late_or_lost=just_over, stalls_cost_rows=False)
    assert Problem(int(old_rule)) == Problem.TIMING


def test_one_condition_number_the_worse_of_the_excitation_and_the_fit() -> None:
    np.testing.assert_array_equal(judged_condition_number(65.0, np.array([10.0, 100.0])), [65.0, 100.0])


def test_problems_read_back_from_the_record_by_name() -> None:
    problems = Problem.ABORTED | Problem.NOT_CALIBRATED | Problem.COIL_OUT_OF_SPEC
    assert problems.names == ["aborted", "not calibrated", "coil out of spec"]
    assert Problem.from_names(problems.names) == problems
    assert not (Problem.NOT_CALIBRATED | Problem.COIL_OUT_OF_SPEC) & TRUST_PROBLEMS


def test_the_judgement_the_early_stop_and_the_batch_path_share_the_rule() -> None:
    """One function, not three copies: changing it changes the judgement, the early stop and the batch path."""
    for module in (judgement, early_stop, batch):
        assert module.trust_problems is trust.trust_problems, module.__name__
        # and used: a module that imported it and kept its own copy of the rule would pass the line above
        calls = [node for node in ast.walk(ast.parse(Path(module.__file__).read_text(encoding="utf-8")))
                 if isinstance(node, ast.Call) and getattr(node.func, "id", None) == "trust_problems"]
        assert calls, f"{module.__name__} imports trust_problems but never calls it"
    for module in (early_stop, batch, edc_bench.identification.analysis):
        assert module.judged_condition_number is trust.judged_condition_number, module.__name__


#: Methods that decide on a piece of text (removeprefix and removesuffix only shape a sentence: not here).
_TEXT_TESTS = ("startswith", "endswith", "split", "rsplit", "find", "rfind", "index", "rindex", "count", "partition",
               "rpartition")

#: Where text is read on purpose, each with why: the upgrade of older records (their problems, the coil's
#: temperature and the baseline's sources were sentences then), a baseline file's sentence of its sources, and
#: words of others that come with no code (socketcand's protocol greeting, a python-can warning).
_READS_TEXT_ON_PURPOSE = {
    "records/reader.py": None,  # the legacy upgrade, the one place that knows an older record's wording
    "verdict/baseline_source.py": ("text.split(' and ')",),
    "runtime/bus.py": ("text.startswith('< hi >')",),
    "runtime/bus_config.py": ("'was not properly shut down' not in line",),
}


def _sentence_decisions(tree: ast.AST) -> list[tuple[int, str]]:
    """Lines that decide on text: a phrase (a string constant with a space) compared, searched for or split on
    (``"watchdog tripped" in flags``, ``source.split(" and ")``); or a reason's, a source's or a person's line's
    text tested (``x_reason.startswith(...)``, ``reason == "..."``, ``words.startswith("rig self-check")``)."""
    def talks(node: ast.AST) -> bool:
        text = ast.unparse(node).lower()
        return any(word in text for word in ("reason", "source", "sentence", "words", "message"))

    def phrase(node: ast.AST) -> bool:
        # a word with a space beside it (" and " too); a lone separator (", ", " ") is not a phrase
        return isinstance(node, ast.Constant) and isinstance(node.value, str) and " " in node.value \
            and sum(ch.isalnum() for ch in node.value) > 1

    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and node.func.attr in _TEXT_TESTS:
            args = [e for a in node.args for e in (a.elts if isinstance(a, ast.Tuple) else [a])]
            by_name = node.func.attr in ("startswith", "endswith") and talks(node.func.value) \
                and not all(isinstance(a, ast.Constant) and len(str(a.value)) <= 2 for a in args)  # "." is punctuation
            if by_name or any(phrase(a) for a in args):
                found.append((node.lineno, ast.unparse(node)))
        elif isinstance(node, ast.Compare) and any(isinstance(op, (ast.Eq, ast.NotEq, ast.In, ast.NotIn))
                                                   for op in node.ops):
            sides = [node.left, *node.comparators]
            if any(phrase(side) for side in sides) or (
                    any(isinstance(s, ast.Constant) and isinstance(s.value, str) and len(s.value) > 12 for s in sides)
                    and any(talks(s) for s in sides)):
                found.append((node.lineno, ast.unparse(node)))
    return sorted(found)


def test_no_code_decides_by_matching_a_sentence() -> None:
    """Outcomes are values; only the record reader's upgrade of older records reads their old wording, and the
    few places that read others' words (listed with why) read them."""
    package = Path(edc_bench.__file__).parent
    found = {}
    for path in package.rglob("*.py"):
        name = path.relative_to(package).as_posix()
        allowed = _READS_TEXT_ON_PURPOSE.get(name, ())
        if allowed is None:
            continue
        lines = [f"{line}: {code}" for line, code in _sentence_decisions(ast.parse(path.read_text(encoding="utf-8")))
                 if code not in allowed]
        if lines:
            found[name] = lines
    assert found == {}


def test_the_guard_finds_a_decision_by_text() -> None:
    tree = ast.parse('if outcome.abort_reason.startswith("internal error"):\n    pass\n'
                     'if stop["reason"] == "verdict certain":\n    pass\n'
                     'x = w.words if w.words.startswith("rig self-check") else ""\n'  # the session's, until #54
                     'on_rig = "rig" in {p.strip() for p in self.source.split(" and ")}\n'  # the baseline's, until #54
                     'if "watchdog tripped" in (abort.figures.get("flags") or []):\n    pass\n'  # pc_stall's, until #54
                     'if "coil out of spec" in record.problems:\n    pass\n'  # classify's, until #54
                     'if first.startswith("edc-bench history:"):\n    pass\n')  # the history's guard's, until #54
    assert [line for line, _ in _sentence_decisions(tree)] == [1, 3, 5, 6, 7, 9, 11]


@pytest.mark.parametrize("legacy", ["variant not calibrated: p-edc-x has no measured new-valve baseline", None])
def test_an_older_record_is_read_in_todays_form(legacy: str | None) -> None:
    from edc_bench.engine.outcome import AbortKind, abort_from_record
    from edc_bench.records.reader import upgraded

    old = {"schema": 3, "verdict": "INVALID", "reasons": [legacy] if legacy else ["aborted: rig fault: over-current"],
           "coil": {"temp_source": "given (--coil-temp-c)", "temp_start_c": 45.0},
           "timing": {"ticks": 100, "overruns": 3},
           "loop": {"abort_reason": None if legacy else "rig fault: over-current", "abort_time_s": 1.5}}
    new = upgraded(old)
    assert new["problems"] == (["not calibrated"] if legacy else ["aborted"])
    assert new["coil"]["temp_given"] is True and new["timing"]["ticks_late"] == 3
    abort = abort_from_record(new["loop"])
    if legacy:
        assert abort is None
    else:
        assert abort.kind is AbortKind.RECORDED and abort.sentence == "rig fault: over-current"
        assert abort.time_s == 1.5
    assert "problems" not in old  # the record read is not changed
