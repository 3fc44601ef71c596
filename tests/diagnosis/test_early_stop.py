"""The early stop's work is spread over the test, so that no call holds a real-time tick past its deadline.

Before: each period's end fed the whole period's rows at once (1.1 ms) and searched the expected end over every
remaining period in one classifier call (5 points per period: 5 ms at the third of twelve periods, 16 ms for a
60 s test), all inside one 1 ms tick. Counted here in rows and classifier points, not in milliseconds (a timed
test would measure the machine); the real-time tests print the longest call (``stop_check_max_us``).
"""

from __future__ import annotations

import numpy as np
import pytest

from edc_bench.bench import run_simulated_test
from edc_bench.config import load_variant
from edc_bench.diagnosis import early_stop
from edc_bench.diagnosis.classifier import default_classifier
from edc_bench.diagnosis.period_fit import BlockAccumulator, accumulate, rows

# a valve just inside the marginal band of the default variant: its verdict becomes certain only after several
# periods (24 s with seed 0), so the expected-end search runs at many period ends
SLOW_TO_DECIDE = "clearance=0.183"


class _CountingClassifier:
    """The station's classifier, counting the points of each call."""

    def __init__(self, inner) -> None:
        self.inner, self.calls = inner, []

    def classify_many(self, features_rel):
        self.calls.append(len(features_rel))
        return self.inner.classify_many(features_rel)

    def verdicts(self, features_rel):
        self.calls.append(len(features_rel))
        return self.inner.verdicts(features_rel)

    def __getattr__(self, name):
        return getattr(self.inner, name)


class _Watch:
    """An observer that keeps the loop's stop rule, and its expected end before each period's end."""

    def __init__(self) -> None:
        self.rule, self.expected = None, {}

    def phase(self, name) -> None:
        pass

    def tick(self, k, loop) -> None:
        self.rule = loop.stop_rule
        self.expected[k] = loop.stop_rule.expected_end_s


@pytest.fixture(scope="module")
def spread_run():
    """A slow-to-decide valve's test, every stop-rule call recorded: (tick, rows smoothed, classifier points)."""
    mp = pytest.MonkeyPatch()
    counting = _CountingClassifier(default_classifier())
    calls, spans, boxes = [], [], []
    real_check, real_rows, real_flags = early_stop.EarlyStop.check, early_stop.rows, early_stop.stop_flags

    def check(self, k, columns):
        spans.clear()
        before = len(counting.calls)
        out = real_check(self, k, columns)
        calls.append((k, sum(spans), sum(counting.calls[before:])))
        return out

    def counted_rows(setup, position_mm, *args):
        spans.append(len(position_mm))
        return real_rows(setup, position_mm, *args)

    def flags(variant, classifier, fit, periods, centres, half_widths, *args):
        out = real_flags(variant, classifier, fit, periods, centres, half_widths, *args)
        boxes.append((periods, centres.copy(), half_widths.copy(), bool(out[1][0]), bool(out[2][0])))
        return out

    mp.setattr(early_stop.EarlyStop, "check", check)
    mp.setattr(early_stop, "rows", counted_rows)
    mp.setattr(early_stop, "stop_flags", flags)
    mp.setattr("edc_bench.diagnosis.classifier.default_classifier", lambda path=None: counting)
    watch = _Watch()
    try:
        result = run_simulated_test(load_variant(), SLOW_TO_DECIDE, 0, observer=watch)
    finally:
        mp.undo()
    return result, watch, calls, boxes


def test_a_slow_to_decide_valve_runs_several_periods_and_stops_certain(spread_run) -> None:
    result, _, _, boxes = spread_run
    assert result.stop["reason"] == "verdict certain" and result.stop["periods"] >= 6
    searched = [b for b in boxes if b[3] and not b[4]]  # trusted, not yet certain: the expected end is searched
    assert len(searched) >= 3


def test_no_call_smooths_more_than_a_step_of_rows_or_asks_the_classifier_more_than_once(spread_run) -> None:
    result, watch, calls, _ = spread_run
    rule = watch.rule
    window = rule.setup.window
    assert len(calls) > 10 * result.stop["periods"]
    assert sum(points for _, _, points in calls) >= 5 * 6  # the classifier was asked, and counted
    for k, span, points in calls:
        assert span <= early_stop.STEP_TICKS + window + 1, (k, span)  # a step's rows and their smoothing margins
        assert points <= 5, (k, points)  # one box: its centre and four corners
        if k not in rule.period_ends:
            assert span == 0 or points == 0, (k, span, points)  # a step feeds or searches, never both
    # the end of a period has only the few rows the reply lag held back left to feed
    for k, span, _ in calls:
        if k in rule.period_ends:
            assert span <= rule.feed_lag_ticks + window + 1, (k, span)


def test_the_expected_end_found_step_by_step_is_the_one_a_search_over_every_period_gives(spread_run) -> None:
    _, watch, _, boxes = spread_run
    rule = watch.rule
    setup = rule.setup
    classifier = default_classifier()
    compared = 0
    for periods, centre, half_width, trusted, certain in boxes:
        if not trusted or certain:
            continue
        more = np.arange(periods + 1, rule.max_periods + 1)
        box = early_stop.certain_verdicts(classifier, np.repeat(centre, len(more), axis=0),
                                          half_width * np.sqrt(periods / more)[:, None])
        expected = setup.end_s(int(more[np.argmax(box)])) if box.any() else rule.duration_s
        # what the live view showed at the last observed tick before the next period's end
        next_end = setup.end_tick(periods + 1)
        shown = watch.expected[max(k for k in watch.expected if k < next_end)]
        assert shown == pytest.approx(expected), periods
        compared += 1
    assert compared >= 3


@pytest.mark.parametrize("adapter", [None, "usb-fs"])
def test_rows_fed_a_step_at_a_time_sum_to_the_rows_of_the_whole_trace(adapter) -> None:
    """The accumulator the stop rule built step by step holds what one pass over the finished trace gives (through
    a USB adapter's late replies too: the feed waits for the oldest reply the loop accepts)."""
    watch = _Watch()
    result = run_simulated_test(load_variant(), "worn", 1, observer=watch, adapter=adapter)
    rule = watch.rule
    periods = result.stop["periods"]
    trace, setup = result.trace, rule.setup
    valid = trace["reply_ok"].astype(bool) & ~trace["gap"].astype(bool)
    X, y, use = rows(setup, trace["position_mm"], trace["drive_v"],
                     trace["coil_resistance_ohm"] / rule.variant.coil.resistance_ohm,
                     trace["reference_velocity_mm_s"], valid)
    whole = BlockAccumulator(setup, periods)
    accumulate(setup, whole, 0, X, y, use)
    # the last period's final rows were fed at its end, before the replies to its last ticks could come
    complete = periods if adapter is None else periods - 1
    np.testing.assert_allclose(rule.acc.A[:complete], whole.A[:complete], rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(rule.acc.z[:complete], whole.z[:complete], rtol=1e-9, atol=1e-12)
    np.testing.assert_array_equal(rule.acc.count[:complete], whole.count[:complete])
    assert (rule.acc.count[periods - 1] >= whole.count[periods - 1] - 2 * rule.feed_lag_ticks).all()
