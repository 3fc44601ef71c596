"""What the technician does after a test, in words they act on, made from typed values only (a leaf beside the
record: the report, which reads records only, gives the same line).

Every place a verdict is shown to the technician (``edc-bench test``'s plain and live output, the report) gives
the same line, built here from the verdict, the test's :class:`~edc_bench.identification.trust.Problem` flags and
the kind of abort, never from the reasons' sentences. The engineer's figures (P(faulty), the distance to the
boundary, the model's hash) stay in the record and the engineer's pages.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass

from edc_bench.engine.outcome import CHECK_BUS, CHECK_PC, CHECK_PUMP, CHECK_RIG, AbortKind, what_to_check
from edc_bench.engine.problems import Problem
from edc_bench.verdict.verdicts import Verdict


class Action(enum.StrEnum):
    """What is done with the valve (or the bench) next."""

    REFIT = "refit"
    REPLACE = "replace"
    RETEST = "retest"
    CHECK = "check"
    CALIBRATE = "calibrate"
    NONE = "none"


@dataclass(frozen=True)
class Advice:
    """The technician's line: what to do, and the words that say it."""

    action: Action
    words: str


#: The trust problems a technician meets at the bench, the first that applies deciding what to check.
_CHECKS: tuple[tuple[Problem, str], ...] = (
    (Problem.NOT_IDENTIFIED, CHECK_RIG),
    (Problem.MODEL_DOES_NOT_FIT, "check the pump's part number (--variant) and the valve's mounting: the pump does "
                                 "not behave as its variant says"),
    (Problem.TIMING, CHECK_PC),
    (Problem.REPLIES_MISSING, CHECK_BUS),
    (Problem.DRIFTING, CHECK_PUMP + ", then retest"),
    (Problem.TOO_FEW_PERIODS, "run the test longer, then retest"),
    (Problem.POORLY_CONDITIONED, CHECK_PUMP + ", then retest"),
)


def advice(verdict: Verdict | str, problems: Problem = Problem.NONE, abort_kind: AbortKind | None = None) -> Advice:
    """The technician's line for a test.

    Parameters
    ----------
    verdict : Verdict
        The test's verdict.
    problems : Problem
        The test's problems (:attr:`~edc_bench.verdict.judgement.Judgement.problems`, or the record's).
    abort_kind : AbortKind, optional
        Why the loop was cut short, if it was.
    """
    verdict = Verdict(verdict)
    if verdict == Verdict.PASS:
        return Advice(Action.REFIT, "reusable: refit the valve")
    if verdict == Verdict.FAIL:
        if Problem.COIL_OUT_OF_SPEC in problems:
            return Advice(Action.REPLACE, "coil out of spec: replace the valve")
        return Advice(Action.REPLACE, "worn: replace the valve")
    if verdict == Verdict.MARGINAL:
        return Advice(Action.RETEST, "near the limit: retest")
    if verdict == Verdict.UNCLASSIFIED:
        return Advice(Action.NONE, "measured, not judged (a test for the new-valve baseline)")
    if Problem.NOT_CALIBRATED in problems:
        return Advice(Action.CALIBRATE, "not judged: this pump type has no new-valve baseline yet: calibrate it "
                                        "(edc-bench calibrate), then retest")
    if Problem.ABORTED in problems and abort_kind is not None:
        return Advice(Action.CHECK, f"not judged: {what_to_check(abort_kind)}")
    for problem, check in _CHECKS:
        if problem in problems:
            return Advice(Action.CHECK, f"not judged: {check}")
    return Advice(Action.CHECK, f"not judged: {CHECK_PUMP}; {CHECK_RIG}")
