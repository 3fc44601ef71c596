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
from edc_bench.config import load_variant, with_changes
from edc_bench.identification import period_fit
from edc_bench.identification.period_fit import trace_blocks
from edc_bench.verdict import early_stop
from edc_bench.verdict.baseline import load_baseline
from edc_bench.verdict.classifier import ValveClassifier, default_classifier

# a valve near the marginal band of the default variant: its verdict becomes certain only after several periods
# (7 with seed 0), so the expected-end search runs at many period ends
SLOW_TO_DECIDE = "clearance=0.1834"  # MARGINAL, certain after 8 periods


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
    """A slow-to-decide valve's test, every stop-rule call recorded: (tick, rows smoothed, points the classifier
    was asked about, points it scanned in full)."""
    mp = pytest.MonkeyPatch()
    calls, spans, asked, full, boxes = [], [], [], [], []
    real_check, real_rows, real_flags = early_stop.EarlyStop.check, period_fit.rows, early_stop.stop_flags
    real_box, made = early_stop.relative_box, []
    real_verdicts, real_many = ValveClassifier.verdicts, ValveClassifier.classify_many

    def check(self, k, columns):
        spans.clear(), asked.clear(), full.clear()
        out = real_check(self, k, columns)
        calls.append((k, sum(spans), sum(asked), sum(full)))
        return out

    def counted_rows(setup, position_mm, *args):
        spans.append(len(position_mm))
        return real_rows(setup, position_mm, *args)

    def box(*args):
        made.append(real_box(*args))
        return made[-1]

    def flags(variant, classifier, fit, periods, centres, half_widths, *args):
        out = real_flags(variant, classifier, fit, periods, centres, half_widths, *args)
        np.testing.assert_array_equal(half_widths, made[-1].half_width)  # the box the rule was asked about
        boxes.append((periods, centres.copy(), made[-1], bool(out[1][0]), bool(out[2][0])))
        return out

    def verdicts(self, features_rel):
        asked.append(len(features_rel))
        return real_verdicts(self, features_rel)

    def classify_many(self, features_rel):
        full.append(len(features_rel))
        return real_many(self, features_rel)

    mp.setattr(early_stop.EarlyStop, "check", check)
    mp.setattr(period_fit, "rows", counted_rows)
    mp.setattr(early_stop, "stop_flags", flags)
    mp.setattr(early_stop, "relative_box", box)
    mp.setattr(ValveClassifier, "verdicts", verdicts)
    mp.setattr(ValveClassifier, "classify_many", classify_many)
    watch = _Watch()
    try:
        result = run_simulated_test(load_variant(), SLOW_TO_DECIDE, 0, observer=watch)
    finally:
        mp.undo()
    return result, watch, calls, boxes


def test_a_slow_to_decide_valve_runs_several_periods_and_stops_certain(spread_run) -> None:
    result, _, _, boxes = spread_run
    assert result.stop.reason == "verdict certain" and result.stop.periods >= 6
    searched = [b for b in boxes if b[3] and not b[4]]  # trusted, not yet certain: the expected end is searched
    assert len(searched) >= 3
    # the stop records the box's fixed parts, the residual's among them; the whole is the last box the rule judged
    box = boxes[-1][2]
    for part in ("misfit", "baseline", "residual"):
        recorded = getattr(result.stop, f"{part}_half_width_rel")
        np.testing.assert_allclose([recorded.af, recorded.a1], getattr(box, part)[0], rtol=1e-12)
    np.testing.assert_allclose([result.stop.half_width_rel.af, result.stop.half_width_rel.a1],
                               (box.statistical + box.misfit + box.baseline + box.residual)[0], rtol=1e-12)


def test_no_call_smooths_more_than_a_step_of_rows_or_asks_the_classifier_more_than_once(spread_run) -> None:
    result, watch, calls, _ = spread_run
    rule = watch.rule
    window = rule.setup.window
    assert len(calls) > 10 * result.stop.periods
    assert sum(asked for _, _, asked, _ in calls) >= 5 * 6  # the classifier was asked, and counted
    for k, span, asked, full in calls:
        assert span <= early_stop.STEP_TICKS + window + 1, (k, span)  # a step's rows and their smoothing margins
        assert asked <= 5 * rule.search_per_step, (k, asked)  # one box per candidate: centre and four corners
        assert full <= asked, (k, full, asked)  # the full boundary scan only for points near the band
        if k not in rule.period_ends:
            assert span == 0 or asked == 0, (k, span, asked)  # a step feeds or searches, never both
    # the end of a period feeds what the reply lag held back: once for good, once as it stands for the decision
    for k, span, _, _ in calls:
        if k in rule.period_ends:
            assert span <= 2 * (rule.feed_lag_ticks + window + 1), (k, span)


def test_the_expected_end_found_step_by_step_is_the_one_a_search_over_every_period_gives(spread_run) -> None:
    _, watch, _, boxes = spread_run
    rule = watch.rule
    setup = rule.setup
    classifier = default_classifier()
    compared = 0
    for periods, centre, box, trusted, certain in boxes:
        more = np.arange(periods + 1, rule.max_periods + 1)
        if not trusted or certain or not len(more):
            continue
        box = early_stop.certain_verdicts(classifier, np.repeat(centre, len(more), axis=0),
                                          box.statistical * rule.interval.shrink(periods, more)[:, None]
                                          + box.fixed)
        expected = setup.end_s(int(more[np.argmax(box)])) if box.any() else rule.duration_s
        # what the live view showed at the last observed tick before the next period's end
        next_end = setup.end_tick(periods + 1)
        shown = watch.expected[max(k for k in watch.expected if k < next_end)]
        assert shown == pytest.approx(expected), periods
        compared += 1
    assert compared >= 3


@pytest.mark.parametrize("adapter", [None, pytest.param("usb-fs", marks=pytest.mark.slow)])  # usb-fs: slow pass
def test_rows_fed_a_step_at_a_time_sum_to_the_rows_of_the_whole_trace(adapter) -> None:
    """The accumulator the stop rule built step by step holds what one pass over the finished trace gives, for
    every period the test went on after (through a USB adapter's late replies too)."""
    watch = _Watch()
    result = run_simulated_test(load_variant(), SLOW_TO_DECIDE, 0, observer=watch, adapter=adapter)
    rule = watch.rule
    periods = result.stop.periods if result.stop.periods is not None else rule.max_periods  # the slow valve may run its full length
    assert periods >= 4
    whole, _ = trace_blocks(rule.setup, result.trace, rule.variant.coil.resistance_ohm)
    done = periods - 1  # the last period's final rows were only added for the decision, then taken out
    np.testing.assert_allclose(rule.acc.A[:done], whole.A[:done], rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(rule.acc.z[:done], whole.z[:done], rtol=1e-9, atol=1e-12)
    np.testing.assert_array_equal(rule.acc.count[:done], whole.count[:done])
    # and the products of each row with the row a period before, which the model-fit check judges by
    for name in ("pair_yy", "pair_xy", "pair_xx", "pair_count"):
        np.testing.assert_allclose(getattr(rule.acc, name)[:done], getattr(whole, name)[:done], rtol=1e-9,
                                   atol=1e-12, err_msg=name)
    held_back = whole.count[done] - rule.acc.count[done]
    assert (0 <= held_back).all() and (held_back <= rule.feed_lag_ticks - rule.setup.window // 2).all()


def test_a_period_s_last_rows_wait_for_their_replies_where_the_rack_slides_across_the_period_s_end() -> None:
    """An excitation whose periods end mid-slide (0.5 Hz and 1.5 Hz: the rack at 17 mm/s there), replies 3 ticks
    late: at each period's end the last rows lack their samples. The decision counts them as missing (as a test
    stopped there would), and the later steps feed them with their replies. Before, they were fed at the end,
    as missing, for good: the stop rule's fit lost up to max_reply_age + 1 sliding rows a period."""
    variant = with_changes(load_variant(), {"excitation": {"tones": [
        {"frequency_hz": 0.5, "amplitude_mm": 4.0}, {"frequency_hz": 1.5, "amplitude_mm": 0.5}]}}, "mid-slide")
    trace = run_simulated_test(variant, "worn", 1, classify=False).trace
    rule = early_stop.EarlyStop(variant, load_baseline(variant), default_classifier())
    setup, late = rule.setup, 3
    boundary = setup.first_tick + 2 * setup.block_ticks
    assert abs(trace["reference_velocity_mm_s"][boundary - 2]) > 2 * setup.exclusion_mm_s  # sliding there
    periods = 5
    last = setup.end_tick(periods)
    for k in sorted(t for t in rule.check_ticks if t <= last):
        columns = dict(trace)
        pending = np.zeros(len(trace["reply_ok"]), dtype=bool)
        pending[k - late + 1: k + 1] = True  # the replies to the last ticks' commands are still on their way
        columns["reply_ok"] = trace["reply_ok"].astype(bool) & ~pending
        rule.check(k, columns)
    whole, _ = trace_blocks(setup, trace, variant.coil.resistance_ohm)
    done = periods - 1
    np.testing.assert_array_equal(rule.acc.count[:done], whole.count[:done])
    np.testing.assert_allclose(rule.acc.A[:done], whole.A[:done], rtol=1e-9, atol=1e-12)


def test_a_long_test_searches_enough_periods_a_step_to_finish_between_two_period_ends() -> None:
    for duration_s in (30.0, 60.0, 120.0):
        variant = with_changes(load_variant(), {"excitation": {"duration_s": duration_s}}, "long")
        rule = early_stop.EarlyStop(variant, load_baseline(variant), default_classifier())
        ends = sorted(rule.period_ends)
        steps = min(sum(1 for t in rule.search_ticks if a < t < b) for a, b in zip(ends, ends[1:]))
        candidates = rule.max_periods - variant.acceptance.min_periods
        assert steps * rule.search_per_step >= candidates, duration_s
        assert (rule.search_per_step == 1) == (duration_s <= 40)  # one a step unless the test is long
