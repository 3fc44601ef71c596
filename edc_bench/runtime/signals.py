"""Operator interrupts: Ctrl-C and SIGTERM abort a test like any other fault,
and a second one cannot skip the safe-state commands or the record.

:func:`interrupt_guard` turns Ctrl-C and SIGTERM into a stop request that
the bench loop polls every tick (:func:`stop_requested`); it never raises an
exception at an arbitrary point (an exception between a lock's acquire and
its release would leave the lock held, and the SAFE commands could then
hang on it). The loop ends the test as an abort with SAFE commands; the
record is still written; further signals are only noted. Guards nest; the
outermost installs and restores the handlers. A signal the parent process
set to be ignored stays ignored.
"""

from __future__ import annotations

import signal
import sys
import threading
from collections.abc import Iterator
from contextlib import contextmanager

_SIGNALS = {signal.SIGINT, signal.SIGTERM}
_state: dict = {"depth": 0, "count": 0, "previous": {}}


def _handler(signum: int, frame: object) -> None:
    _state["count"] += 1
    if _state["count"] > 1:
        sys.stderr.write("\nedc-bench: interrupt noted; still bringing the rig to its safe state and writing the record\n")


def stop_requested() -> bool:
    """True once Ctrl-C or SIGTERM has arrived inside a guard."""
    return _state["count"] > 0


@contextmanager
def interrupt_guard() -> Iterator[None]:
    """Within the block, Ctrl-C and SIGTERM request a stop (see :func:`stop_requested`) instead of raising."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    if _state["depth"] == 0:
        _state["count"] = 0
        for sig in _SIGNALS:
            if signal.getsignal(sig) is not signal.SIG_IGN:
                _state["previous"][sig] = signal.signal(sig, _handler)
    _state["depth"] += 1
    try:
        yield
    finally:
        _state["depth"] -= 1
        if _state["depth"] == 0:
            for sig, previous in _state["previous"].items():
                signal.signal(sig, previous)
            _state["previous"] = {}
