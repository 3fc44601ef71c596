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
from edc_bench.verdict.part_sections import Part, PartDiagnosis
from edc_bench.verdict.part_words import RACK_CHECK, part_words
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
    # a rack or sensor fault the part diagnosis could not tell apart (a sensor's step near the swing's end) shows
    # as a misfit too
    (Problem.MODEL_DOES_NOT_FIT, "check the pump's part number (--variant) and the valve's mounting, then that the "
                                 "rack moves freely and the rack-travel sensor reads true over its travel: the pump "
                                 "does not behave as its variant says"),
    (Problem.TIMING, CHECK_PC),
    (Problem.REPLIES_MISSING, CHECK_BUS),
    (Problem.DRIFTING, CHECK_PUMP + ", then retest"),
    (Problem.TOO_FEW_PERIODS, "run the test longer, then retest"),
    (Problem.POORLY_CONDITIONED, CHECK_PUMP + ", then retest"),
)


def advice(verdict: Verdict | str, problems: Problem = Problem.NONE, abort_kind: AbortKind | None = None,
           part: PartDiagnosis | None = None) -> Advice:
    """The technician's line for a test.

    Parameters
    ----------
    verdict : Verdict
        The test's verdict.
    problems : Problem
        The test's problems (:attr:`~edc_bench.verdict.judgement.Judgement.problems`, or the record's).
    abort_kind : AbortKind, optional
        Why the loop was cut short, if it was.
    part : PartDiagnosis, optional
        Which part is at fault (:mod:`edc_bench.verdict.part`): a rack or sensor at fault is what the technician
        sees to first, whatever else the test found; friction the same along the stroke adds the rack's check by
        hand to a worn valve's line. None: the valve alone was judged (older records).
    """
    verdict = Verdict(verdict)
    even = part is not None and part.part is Part.VALVE_OR_RACK
    if verdict == Verdict.PASS:
        if even:
            return Advice(Action.REFIT, "reusable: refit the valve; friction high along the whole stroke: check by "
                                        "hand that the rack moves freely")
        return Advice(Action.REFIT, "reusable: refit the valve")
    if verdict == Verdict.FAIL:
        if Problem.COIL_OUT_OF_SPEC in problems:
            return Advice(Action.REPLACE, "coil out of spec: replace the valve")
        if even:
            return Advice(Action.REPLACE, f"worn valve or a dragging rack: {RACK_CHECK}, then replace the valve")
        return Advice(Action.REPLACE, "worn: replace the valve")
    if verdict == Verdict.MARGINAL:
        return Advice(Action.RETEST, "near the limit: retest" + (f"; {RACK_CHECK}" if even else ""))
    if part is not None and not part.valve_judged and Problem.PC_STALLED not in problems \
            and abort_kind is not AbortKind.INTERRUPTED:
        return Advice(Action.CHECK, f"not judged: {part_words(part)}")
    if verdict == Verdict.UNCLASSIFIED:
        return Advice(Action.NONE, "measured, not judged (a test for the new-valve baseline)")
    if Problem.NOT_CALIBRATED in problems:
        return Advice(Action.CALIBRATE, "not judged: this pump type has no new-valve baseline yet: calibrate it "
                                        "(edc-bench calibrate), then retest")
    if Problem.PC_STALLED in problems:  # the abort names the rig or the bus; a stall of the PC caused it
        return Advice(Action.CHECK, "not judged: the PC stalled, not the rig: close other programs or run "
                                    "check-station, then retest")
    if Problem.ABORTED in problems and abort_kind is not None:
        return Advice(Action.CHECK, f"not judged: {what_to_check(abort_kind)}")
    for problem, check in _CHECKS:
        if problem in problems:
            return Advice(Action.CHECK, f"not judged: {check}")
    return Advice(Action.CHECK, f"not judged: {CHECK_PUMP}; {CHECK_RIG}")


class Cause(enum.StrEnum):
    """Who an INVALID test points at: what the customer's page says, and whether a second one escalates."""

    VALVE = "valve"  # the valve itself can do this: a seized or very worn valve does
    BENCH = "bench"  # the rig, its link or the PC
    EITHER = "valve or bench"  # a fault the valve or the rig may have caused
    INTERRUPTED = "interrupted"
    NOT_SET_UP = "not set up"  # the pump type has no new-valve baseline yet
    PUMP = "pump"  # the pump's control rack or rack-travel sensor (the part diagnosis), not the valve or the bench


#: aborts a seized or very worn valve causes: the rack does not follow the reference
_VALVE_ABORTS = frozenset({AbortKind.OFF_REFERENCE})
#: aborts the valve's coil or the rig may cause (an over-current, a reading out of range)
_EITHER_ABORTS = frozenset({AbortKind.RIG_FAULT, AbortKind.SAMPLE_OUT_OF_RANGE})
#: problems a valve that sticks or is far worn causes: the model does not fit it, its figures do not settle, the
#: rack's movement does not make them identifiable
_VALVE_PROBLEMS = Problem.MODEL_DOES_NOT_FIT | Problem.DRIFTING | Problem.POORLY_CONDITIONED


def invalid_cause(problems: Problem = Problem.NONE, abort_kind: AbortKind | None = None) -> Cause:
    """Who an INVALID test points at, from its problems and the kind of its abort (typed values only)."""
    if Problem.PC_STALLED in problems:
        return Cause.BENCH
    if Problem.PUMP_FAULT in problems and abort_kind is not AbortKind.INTERRUPTED:
        return Cause.PUMP
    if Problem.NOT_CALIBRATED in problems:
        return Cause.NOT_SET_UP
    if abort_kind is not None and Problem.ABORTED in problems:
        if abort_kind is AbortKind.INTERRUPTED:
            return Cause.INTERRUPTED
        if abort_kind in _VALVE_ABORTS:
            return Cause.VALVE
        return Cause.EITHER if abort_kind in _EITHER_ABORTS else Cause.BENCH
    if problems & (Problem.NOT_IDENTIFIED | Problem.TIMING | Problem.REPLIES_MISSING):
        return Cause.BENCH
    return Cause.VALVE if problems & _VALVE_PROBLEMS else Cause.EITHER


class Area(enum.StrEnum):
    """Where an INVALID test points the technician: the first thing to check (the chain's ranking of INVALID causes,
    indexed as ``tests.invalid_area``). The values are what the history stores."""

    RIG = "rig"
    MOUNTING = "mounting"
    BUS = "bus"
    PC = "PC"
    CALIBRATION = "calibration"
    INTERRUPTED = "interrupted"
    OTHER = "other"
    PUMP = "pump"  # the pump's control rack or rack-travel sensor (the part diagnosis; the part itself: tests.part)


#: each abort's area: the first check :func:`~edc_bench.engine.outcome.what_to_check` names for it
_ABORT_AREAS = {
    AbortKind.RIG_NOT_READY: Area.RIG, AbortKind.NO_SYNC_REPLY: Area.RIG, AbortKind.AMPLIFIER_OFF: Area.RIG,
    AbortKind.RIG_FAULT_STATE: Area.RIG, AbortKind.SILENCE: Area.RIG, AbortKind.HEARTBEAT_LOST: Area.RIG,
    AbortKind.RIG_FAULT: Area.MOUNTING, AbortKind.SAMPLE_OUT_OF_RANGE: Area.MOUNTING,
    AbortKind.OFF_REFERENCE: Area.MOUNTING,
    AbortKind.SLOW_LINK: Area.BUS, AbortKind.REPLIES_MISSING: Area.BUS, AbortKind.BUS_FLOODED: Area.BUS,
    AbortKind.FOREIGN_COMMAND: Area.BUS, AbortKind.BUS_ERROR: Area.BUS,
    AbortKind.INTERRUPTED: Area.INTERRUPTED,
}

#: each trust problem's area, in the order :func:`advice` checks them
_PROBLEM_AREAS = ((Problem.NOT_IDENTIFIED, Area.RIG), (Problem.MODEL_DOES_NOT_FIT, Area.MOUNTING),
                  (Problem.TIMING, Area.PC), (Problem.REPLIES_MISSING, Area.BUS), (Problem.DRIFTING, Area.MOUNTING),
                  (Problem.POORLY_CONDITIONED, Area.MOUNTING))


def invalid_area(problems: Problem = Problem.NONE, abort_kind: AbortKind | None = None) -> Area:
    """Where an INVALID test points the technician, by the same rule as its :func:`advice` (typed values only)."""
    if Problem.PC_STALLED in problems:
        return Area.PC
    if Problem.PUMP_FAULT in problems and abort_kind is not AbortKind.INTERRUPTED:
        return Area.PUMP
    if Problem.NOT_CALIBRATED in problems:
        return Area.CALIBRATION
    if Problem.ABORTED in problems and abort_kind is not None:
        return _ABORT_AREAS.get(abort_kind, Area.OTHER)
    for problem, area in _PROBLEM_AREAS:
        if problem in problems:
            return area
    return Area.OTHER


#: what the customer's page says of an INVALID test, by its cause: no figure, no engineer's word
CUSTOMER_WORDS = {
    Cause.VALVE: "The valve did not move as a sound valve does, so the bench could not measure it: it may be "
                 "sticking or badly worn.",
    Cause.BENCH: "The test bench could not complete the measurement: a fault of the bench or its connections, not "
                 "a finding on the valve.",
    Cause.EITHER: "The measurement could not be completed: the valve or the bench may be the cause.",
    Cause.INTERRUPTED: "The test was stopped before it was complete.",
    Cause.NOT_SET_UP: "The bench is not yet set up to judge this pump type.",
    Cause.PUMP: "The pump's control rack or its rack-travel sensor is faulty, so the valve could not be judged: "
                "the pump needs that part repaired first, then the valve is tested again.",
}

#: the technician's line when the same valve is INVALID a second time for a cause the valve itself can cause
SEIZED = "not judged twice, each time for a cause the valve itself can cause: the valve may be seized: replace it, " \
         "or escalate to the engineer"


def escalation(first: Cause | None, second: Cause) -> Advice | None:
    """The technician's line when a valve INVALID for ``first`` (None: not INVALID) is INVALID again for
    ``second``: escalated when both times the valve itself can be the cause, else None (the test's own advice)."""
    if first is Cause.VALVE and second is Cause.VALVE:
        return Advice(Action.REPLACE, SEIZED)
    return None
