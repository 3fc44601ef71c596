"""The early stop's worker thread (runtime.stop_worker): the real-time loop's stop rule runs beside the ticks.

CI's slow pass on an Intel Xeon: a decision at a period's end took 5-22 ms inside a 1 ms tick, every real-time
test lost 1.2-1.4 % of its ticks (INVALID over the 1 % limit), and a 20.2 ms call tripped the rig's watchdog.
"""

from __future__ import annotations

import sys
import threading
import time

import pytest

from edc_bench.bench import run_simulated_test
from edc_bench.config import load_variant
from edc_bench.identification.period_fit import FitSetup
from edc_bench.replay import EARLY_STOP_LAG_TICKS, _ends_at_a_period
from edc_bench.runtime.stop_worker import SWITCH_INTERVAL_S, StopWorker

WAIT_S = 30.0  # how long a test waits for the worker before it counts as hung (never a timing assertion)


class FakeEngine:
    """Records the ticks its stop rule was called for; decides at ``decide_at``; fails at ``fail_at``; the call
    for ``hold_at`` waits until released."""

    def __init__(self, decide_at: int = -1, fail_at: int = -1, hold_at: int = -1) -> None:
        self.calls: list[int] = []
        self.decide_at, self.fail_at, self.hold_at = decide_at, fail_at, hold_at
        self.holding, self.release, self.done = threading.Event(), threading.Event(), threading.Event()

    def stop_rule_call(self, k: int) -> dict | None:
        self.calls.append(k)
        if k == self.hold_at:
            self.holding.set()
            assert self.release.wait(WAIT_S)
        if k == self.fail_at:
            self.done.set()
            raise ValueError("the fit broke")
        if k == self.decide_at:
            self.done.set()
            return {"reason": "verdict certain", "time_s": 1.0}
        return None


def test_the_worker_calls_the_rule_in_order_and_hands_back_its_decision_with_the_tick() -> None:
    engine = FakeEngine(decide_at=7)
    worker = StopWorker(engine)
    worker.start()
    try:
        assert worker.decision() is None
        for k in range(12):
            worker.hand_over(k)
        assert engine.done.wait(WAIT_S)
        worker.close()
        assert worker.decision() == ({"reason": "verdict certain", "time_s": 1.0}, 7)
        assert engine.calls == list(range(8))  # in order, and none after the decision
    finally:
        worker.close()


def test_a_failure_of_the_rule_is_raised_in_the_loops_thread() -> None:
    engine = FakeEngine(fail_at=2)
    worker = StopWorker(engine)
    worker.start()
    for k in range(4):
        worker.hand_over(k)
    assert engine.done.wait(WAIT_S)
    waited = time.monotonic() + WAIT_S
    while worker._thread.is_alive() and time.monotonic() < waited:
        time.sleep(0.001)  # waiting for the worker to end, not timing it
    with pytest.raises(ValueError, match="the fit broke"):
        worker.decision()  # at the loop's next poll, in its thread
    assert worker.close() is None  # said once


def test_a_failure_of_the_rules_last_call_is_returned_when_the_worker_closes() -> None:
    """The last period's end is the last tick: its call may fail after the loop's last poll; close() says it."""
    engine = FakeEngine(fail_at=3)
    worker = StopWorker(engine)
    worker.start()
    for k in range(4):
        worker.hand_over(k)
    error = worker.close()  # not cancelled: the calls handed over are made first
    assert isinstance(error, ValueError) and engine.calls == [0, 1, 2, 3]


def test_closing_makes_the_calls_handed_over_and_keeps_their_decision() -> None:
    engine = FakeEngine(decide_at=5)
    worker = StopWorker(engine)
    worker.start()
    for k in range(6):
        worker.hand_over(k)
    assert worker.close() is None
    assert worker.made() == ({"reason": "verdict certain", "time_s": 1.0}, 5)


def test_cancel_drops_the_ticks_not_begun_and_close_restores_the_switch_interval() -> None:
    before = sys.getswitchinterval()
    engine = FakeEngine(hold_at=1)
    worker = StopWorker(engine)
    worker.start()
    assert sys.getswitchinterval() == pytest.approx(SWITCH_INTERVAL_S)
    for k in range(1, 6):
        worker.hand_over(k)
    assert engine.holding.wait(WAIT_S)
    worker.cancel()  # the ticks are over while the call for tick 1 is under way
    engine.release.set()
    worker.close()
    assert engine.calls == [1]
    assert worker.decision() is None
    assert sys.getswitchinterval() == pytest.approx(before)


def test_in_simulated_time_the_rule_decides_inside_the_tick() -> None:
    """Simulated time keeps the rule in the tick (the same test, the same record): decided when it ended."""
    result = run_simulated_test(load_variant(), "new")
    assert result.stop.reason == "verdict certain"
    assert result.stop.decided_s == pytest.approx(result.stop.time_s)
    assert result.outcome.ticks_run == round(result.stop.time_s / load_variant().controller.period_s)


def test_a_raw_log_ending_a_little_after_a_whole_period_ended_by_an_early_stop() -> None:
    variant = load_variant()
    setup = FitSetup.from_variant(variant)
    end = setup.end_tick(variant.acceptance.min_periods) + 1  # ticks in the log when stopped at that period's end
    assert _ends_at_a_period(variant, end)
    assert _ends_at_a_period(variant, end + 14)  # decided 14 ticks later, as measured in real time here
    assert not _ends_at_a_period(variant, end + EARLY_STOP_LAG_TICKS + 1)
    assert not _ends_at_a_period(variant, end - 1)  # before the minimum whole periods


def test_the_worker_is_idle_only_when_every_call_handed_over_is_done() -> None:
    """The loop calls the rule itself only while the worker is idle: never beside it, never out of order."""
    engine = FakeEngine(hold_at=1)
    worker = StopWorker(engine)
    worker.start()
    try:
        assert worker.idle()
        worker.hand_over(1)
        worker.hand_over(2)
        assert not worker.idle()
        assert engine.holding.wait(WAIT_S)
        assert not worker.idle()  # the call for tick 1 is under way
        engine.release.set()
        waited = time.monotonic() + WAIT_S
        while not worker.idle() and time.monotonic() < waited:
            time.sleep(0.001)  # waiting for the worker, not timing it
        assert worker.idle() and engine.calls == [1, 2]
    finally:
        worker.close()
