"""#54 item 4: the tick engine refuses a call out of order (as h11's state table does). Before, a wrong order of
receive/command/sent/check gave other numbers instead of an error. Table-driven: each row drives a started engine
(or a fresh one) to a state, makes one wrong call, and expects the error naming where the engine was."""

from __future__ import annotations

from collections.abc import Callable

import pytest

from edc_bench.config import Variant
from edc_bench.engine.outcome import StopDecision, StopReason
from edc_bench.engine.order import ORDER, EngineOrderError
from edc_bench.engine.tick import TickEngine
from edc_bench.protocol import RIG_FEEDBACK_ID, RIG_HEARTBEAT_ID, FaultCode, Icd, RigState

SYNC = 41


def _fresh(variant: Variant, icd: Icd) -> TickEngine:
    return TickEngine(variant, icd, 100)


def _start(engine: TickEngine, icd: Icd) -> None:
    engine.receive(RIG_HEARTBEAT_ID, icd.make_heartbeat(RigState.READY, FaultCode.NONE, 1, 0, 24.0), 0.0)
    sync = engine.receive(RIG_FEEDBACK_ID, icd.make_rig_feedback(SYNC, position_mm=10.0, current_a=0.5,
                                                                 amp_enabled=True, watchdog_tripped=False,
                                                                 over_current=False, lvdt_fault=False,
                                                                 travel_limit=False), 0.0)
    engine.start(sync, SYNC, t_start_s=0.002, sync_s=0.001)


def _tick(engine: TickEngine, k: int) -> None:
    engine.command(k)
    engine.sent(k, engine.tick_time_s(k), 0.0)


Setup = Callable[[TickEngine, Icd], None]
Call = Callable[[TickEngine, Icd], object]


def nothing(engine: TickEngine, icd: Icd) -> None:
    """A fresh engine: not started."""


def started(engine: TickEngine, icd: Icd) -> None:
    _start(engine, icd)


def one_tick(engine: TickEngine, icd: Icd) -> None:
    _start(engine, icd)
    _tick(engine, 0)


def commanded(engine: TickEngine, icd: Icd) -> None:
    _start(engine, icd)
    engine.command(0)


def finished(engine: TickEngine, icd: Icd) -> None:
    one_tick(engine, icd)
    engine.finish()


WRONG: list[tuple[str, Setup, Call, str]] = [
    ("a command before start", nothing, lambda e, i: e.command(0), "the ticks have not started"),
    ("a check before start", nothing, lambda e, i: e.check(0), "the ticks have not started"),
    ("a stop check before start", nothing, lambda e, i: e.stop_check(0), "the ticks have not started"),
    ("a skip before start", nothing, lambda e, i: e.skip(0, 1), "the ticks have not started"),
    ("a stop taken before start", nothing, lambda e, i: e.take_stop(StopDecision(StopReason.VERDICT_CERTAIN, 0.006, 3), 0), "the ticks have not started"),
    ("start twice", started, lambda e, i: _start(e, i), "no tick has run yet"),
    ("sent without a command", started, lambda e, i: e.sent(0, 0.0, 0.0), "no tick has run yet"),
    ("a tick ahead of its turn", started, lambda e, i: e.command(1), "the next is tick 0"),
    ("a tick again", one_tick, lambda e, i: e.command(0), "the last tick run is 0; the next is tick 1"),
    ("a second command before the first is sent", commanded, lambda e, i: e.command(1),
     "tick 0's command is not marked sent yet"),
    ("another tick marked sent", commanded, lambda e, i: e.sent(1, 0.0, 0.0), "tick 0's command is not marked sent"),
    ("a check before the command is sent", commanded, lambda e, i: e.check(0), "tick 0's command is not marked"),
    ("a check of a tick not run", one_tick, lambda e, i: e.check(1), "the last tick run is 0"),
    ("a check of an older tick", one_tick, lambda e, i: (_tick(e, 1), e.check(0)), "the last tick run is 1"),
    ("a stop check of a tick not run", one_tick, lambda e, i: e.stop_check(1), "the last tick run is 0"),
    ("a skip while a command is unsent", commanded, lambda e, i: e.skip(0, 2), "tick 0's command is not marked"),
    ("a skip of the wrong ticks", one_tick, lambda e, i: e.skip(5, 1), "the next is tick 1"),
    ("a skip of no tick", one_tick, lambda e, i: e.skip(1, 0), "the next is tick 1"),
    ("a start delayed after a tick", one_tick, lambda e, i: e.delay_start(1.0), "the last tick run is 0"),
    ("a stop taken for a tick not run", one_tick, lambda e, i: e.take_stop(StopDecision(StopReason.VERDICT_CERTAIN, 0.006, 3), 3), "the last tick run is 0"),
    ("a command after finish", finished, lambda e, i: e.command(1), "the ticks are finished"),
    ("a check after finish", finished, lambda e, i: e.check(0), "the ticks are finished"),
    ("start after finish", finished, lambda e, i: _start(e, i), "the ticks are finished"),
]


@pytest.mark.parametrize(("setup", "call", "where"), [row[1:] for row in WRONG], ids=[row[0] for row in WRONG])
def test_a_call_out_of_order_raises_naming_where_the_engine_is(variant: Variant, icd: Icd, setup: Setup, call: Call,
                                                               where: str) -> None:
    engine = _fresh(variant, icd)
    setup(engine, icd)
    with pytest.raises(EngineOrderError) as raised:
        call(engine, icd)
    assert where in str(raised.value) and ORDER in str(raised.value)


def test_the_legal_orders_run(variant: Variant, icd: Icd) -> None:
    """The drivers' orders: ticks with checks, a stall's skip, a stop taken inside a tick and after finish, finish
    before any tick, frames and SAFE at any time."""
    never = _fresh(variant, icd)
    never.finish()  # a test that ended waiting for READY
    never.safe_command()
    engine = _fresh(variant, icd)
    _start(engine, icd)
    engine.delay_start(0.005)
    for k in range(3):
        _tick(engine, k)
        assert engine.check(k) is None and engine.stop_check(k) is None
    engine.skip(3, 4)
    _tick(engine, 7)
    engine.check(7)
    engine.take_stop(StopDecision(StopReason.VERDICT_CERTAIN, 0.006, 3), 7)
    assert engine.outcome.stop is not None and engine.outcome.stop.decided_s is not None  # typed, with when taken
    engine.finish()
    engine.take_stop(StopDecision(StopReason.VERDICT_CERTAIN, 0.006, 3), 7)  # the worker's decision, after the ticks
    engine.safe_command()
    assert engine.outcome.ticks_lost == 4 and engine.outcome.ticks_run == 8
