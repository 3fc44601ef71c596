"""The early stop's decisions beside the real-time ticks, in a worker thread.

A decision at a period's end (a fit, its interval, two classifier calls)
took 16-22 ms in real time on CI's Intel Xeon (docs/bench-test.md prints its
cost in simulated time). Inside a 1 ms tick that lost ticks at every
period's end, and a 20 ms call tripped the rig's watchdog. In real time the
loop therefore hands each period's end to this worker and takes the
decision at the first tick after it is made: the test ends a few ticks
after the period it was decided on (the record's ``stop.decided_s`` beside
``stop.time_s``), and the verdict's fit takes whole periods only, so those
ticks change nothing in it. The short calls (feeds, search steps) stay in
the tick while the worker is idle (:meth:`StopWorker.idle`); while it is
not, they are handed to it too, in order.

While the worker runs, the interpreter's switch interval is cut to
:data:`SWITCH_INTERVAL_S`, so a wake-up of the loop waits about that long
for it at most. In simulated time the rule runs inside the tick, as before:
the same test gives the same record.
"""

from __future__ import annotations

import queue
import sys
import threading
from typing import Protocol

from edc_bench.engine.outcome import StopDecision

#: The interpreter's switch interval while the worker runs (Python's default, 5 ms, would let the worker hold
#: the interpreter through five ticks).
SWITCH_INTERVAL_S = 100e-6

_END = -1


class _Engine(Protocol):
    def stop_rule_call(self, k: int) -> StopDecision | None: ...


class StopWorker:
    """Runs ``engine.stop_rule_call(k)`` for the ticks handed over, in order, in a daemon thread.

    Parameters
    ----------
    engine : TickEngine
        The test's engine (its stop rule reads the trace rows the loop has written for good).

    :meth:`start` it before the ticks; :meth:`cancel` it when they end (the ticks handed over and not begun are
    dropped, at once); :meth:`close` it once the rig is safe (it waits for the call under way, and restores the
    interpreter's switch interval).
    """

    def __init__(self, engine: _Engine) -> None:
        self._engine = engine
        self._ticks: queue.SimpleQueue[int] = queue.SimpleQueue()
        self._decision: tuple[StopDecision, int] | None = None
        self._error: BaseException | None = None
        self._ended = threading.Event()
        self._thread = threading.Thread(target=self._run, name="early-stop", daemon=True)
        self._switch_interval_s: float | None = None  # the interpreter's, while the worker runs
        # ticks handed over, and calls done: each written by one thread only (the loop's, the worker's)
        self._handed = 0
        self._done = 0

    def start(self) -> None:
        """Start the worker, and cut the switch interval while it runs."""
        self._switch_interval_s = sys.getswitchinterval()
        sys.setswitchinterval(SWITCH_INTERVAL_S)
        self._thread.start()

    def hand_over(self, k: int) -> None:
        """Tick ``k`` is over: the rule's call for it, if it has one, is the worker's to make."""
        self._handed += 1
        self._ticks.put(k)

    def idle(self) -> bool:
        """True when every call handed over is done: the loop may make a short call itself, in order."""
        return self._done == self._handed

    def decision(self) -> tuple[StopDecision, int] | None:
        """The rule's decision and the tick it was made for, once made; a failure of the rule is raised here, in
        the loop's thread, as it would have been inside the tick."""
        if self._error is not None:
            error, self._error = self._error, None
            raise error
        return self._decision

    def made(self) -> tuple[StopDecision, int] | None:
        """The decision, if made (never raises: :meth:`close` returns a failure)."""
        return self._decision

    def _run(self) -> None:
        engine, ticks, ended = self._engine, self._ticks, self._ended
        while True:
            k = ticks.get()
            if k == _END or ended.is_set():
                return
            try:
                decision = engine.stop_rule_call(k)
            except Exception as exc:  # noqa: BLE001 - handed to the loop, which ends the test safely
                self._error = exc
                return
            if decision is not None:
                self._decision = (decision, k)
                return
            self._done += 1  # after the call: the loop makes none of its own until the rule is left alone

    def cancel(self) -> None:
        """No more calls: the worker ends after the one under way (without waiting for it); the calls handed over
        and not begun are dropped."""
        self._ended.set()
        self._ticks.put(_END)

    def close(self) -> BaseException | None:
        """End the worker, after the calls handed over (all of them, unless :meth:`cancel` dropped them), and
        restore the interpreter's switch interval; the rule's failure, if one is still to be said."""
        try:
            self._ticks.put(_END)
            if self._thread.is_alive():
                self._thread.join()
        finally:
            if self._switch_interval_s is not None:
                sys.setswitchinterval(self._switch_interval_s)
                self._switch_interval_s = None
        error, self._error = self._error, None
        return error


__all__ = ["SWITCH_INTERVAL_S", "StopWorker"]
