"""The tick engine's call order, as values: where a test's ticks are, and the error a call out of order raises.

A wrong order of :class:`~edc_bench.engine.tick.TickEngine`'s calls once gave other numbers instead of an error
(a command not marked sent, a check of a tick not run). The engine now keeps its :class:`EnginePhase` and the
tick it expects, and refuses a call that does not fit, as h11's ``Connection`` refuses an event its state does not
allow.
"""

from __future__ import annotations

import enum

#: The order, as the error says it.
ORDER = ("start(sync, ...); then per tick: command(k), sent(k, ...), check(k) and stop_check(k) (skip(k, lost) "
         "for ticks a host stall cost); finish(); receive(...), safe_command() and take_stop(..., k) of a tick run "
         "at any time after start")


class EnginePhase(enum.IntEnum):
    """Where a test's ticks are."""

    IDLE = 0  # not started: frames are read, no tick runs
    TICKING = 1  # between start() and finish()
    FINISHED = 2  # after finish(): replies that still come are not the test's


class EngineOrderError(RuntimeError):
    """A :class:`~edc_bench.engine.tick.TickEngine` call out of order: a bug in its driver, never the rig's."""


def order_error(call: str, phase: int, expected_k: int, commanded_k: int) -> EngineOrderError:
    """The error for ``call`` (``"command(7)"``) made in ``phase``, the engine expecting tick ``expected_k`` and
    holding tick ``commanded_k``'s command unsent (-1: none)."""
    if phase == EnginePhase.IDLE:
        where = "the ticks have not started"
    elif phase == EnginePhase.FINISHED:
        where = "the ticks are finished"
    elif commanded_k >= 0:
        where = f"tick {commanded_k}'s command is not marked sent yet"
    elif expected_k == 0:
        where = "no tick has run yet; the next is tick 0"
    else:
        where = f"the last tick run is {expected_k - 1}; the next is tick {expected_k}"
    return EngineOrderError(f"TickEngine.{call} out of order: {where}. The order: {ORDER}")


__all__ = ["ORDER", "EngineOrderError", "EnginePhase", "order_error"]
