"""The loop's check that the rack follows its reference (edc_bench.engine.tracking)."""

from __future__ import annotations

from edc_bench.engine.outcome import Abort, AbortKind
from edc_bench.engine.tracking import OffReferenceRun


def _run(run: OffReferenceRun, positions_mm: list[float], reference_mm: float = 10.0) -> list[str | None]:
    """The abort's sentence at each tick (None while the rack may still stray)."""
    return [Abort(AbortKind.OFF_REFERENCE, run.figures()).sentence if run.update(reference_mm, x) else None
            for x in positions_mm]


def test_a_stuck_rack_ends_the_test_after_exactly_the_limit_and_says_stuck() -> None:
    run = OffReferenceRun(max_error_mm=2.0, ticks_limit=100)
    reasons = _run(run, [7.0] * 100)
    assert reasons[:-1] == [None] * 99
    assert reasons[-1] == ("rack does not follow its reference: more than 2 mm off for 100 ticks, moving 0.00 mm "
                           "meanwhile (stuck rack or sensor)")


def test_a_rack_that_sticks_and_breaks_away_is_stick_slip_not_a_fault() -> None:
    """Runs of 50 ticks off (as a faulty valve sticks on a pump the model fits badly) never add up."""
    run = OffReferenceRun(max_error_mm=2.0, ticks_limit=100)
    for _ in range(20):
        assert _run(run, [7.2] * 50 + [9.5] * 10) == [None] * 60
    assert run.ticks == 0


def test_exactly_the_limit_off_is_still_on_the_reference() -> None:
    run = OffReferenceRun(max_error_mm=2.0, ticks_limit=3)
    assert _run(run, [8.0, 12.0, 8.0, 12.0]) == [None] * 4
    assert run.ticks == 0


def test_a_rack_that_moves_without_following_is_told_apart_from_a_stuck_one() -> None:
    run = OffReferenceRun(max_error_mm=2.0, ticks_limit=4)
    reasons = _run(run, [5.0, 4.0, 3.0, 2.5])  # running away from the reference (a reversed drive, say)
    assert reasons[-1] is not None and "moving 2.50 mm meanwhile" in reasons[-1]
    assert "the loop cannot hold it" in reasons[-1] and "stuck" not in reasons[-1]
    # a new run starts from its own first position
    run = OffReferenceRun(max_error_mm=2.0, ticks_limit=2)
    assert _run(run, [1.0, 10.0, 7.5, 7.6]) == [None, None, None,
                                               "rack does not follow its reference: more than 2 mm off for 2 "
                                               "ticks, moving 0.10 mm meanwhile (stuck rack or sensor)"]
