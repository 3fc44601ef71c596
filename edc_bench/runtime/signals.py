"""Operator interrupts: Ctrl-C and SIGTERM abort a test like any other fault,
and a second one cannot skip the safe-state commands or the record.

:func:`interrupt_guard` turns Ctrl-C and SIGTERM into a stop request that
the bench loop polls every tick (:func:`stop_requested`); it never raises an
exception at an arbitrary point (an exception between a lock's acquire and
its release would leave the lock held, and the SAFE commands could then
hang on it). The loop ends the test as an abort with SAFE commands; the
record is still written; further signals are only noted. Guards nest; the
outermost installs and restores the handlers, and at its end raises the
interrupt it held back as :class:`KeyboardInterrupt` (unless its owner says
the interrupt itself), so that no caller goes on as if the test had run
whole. A signal the parent process set to be ignored stays ignored.

Outside a guard, :func:`raise_on_interrupt` makes SIGTERM raise
:class:`KeyboardInterrupt` as Ctrl-C does (the two mean the same everywhere),
and notes that it did (:func:`interrupt_raised`): a library interrupted in
the middle of its work may turn the :class:`KeyboardInterrupt` into an error
of its own (a compiled module's ``ImportError: initialization failed``,
pydantic's ``SchemaError``), which is still the operator's interrupt.
"""

from __future__ import annotations

import signal
import sys
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Any

_SIGNALS = {signal.SIGINT, signal.SIGTERM}


@dataclass
class _Interrupts:
    """The process's interrupt state (one per process: signal handlers are)."""

    #: guards open now (the outermost installs and restores the handlers)
    depth: int = 0
    #: signals received inside the open guards
    count: int = 0
    #: the handlers the outermost guard replaced, to put back
    previous: dict[signal.Signals, Any] = field(default_factory=dict)
    #: whether a signal raised KeyboardInterrupt in a raise_on_interrupt block
    raised: bool = False
    #: whether a raise_on_interrupt block is open now
    raising: bool = False
    #: whether the open raise_on_interrupt block's command has settled its outcome (:func:`settle`)
    settled: bool = False
    #: signals that came after it settled (noted, not raised)
    after_settled: int = 0


_state = _Interrupts()


def _handler(signum: int, frame: object) -> None:
    _state.count += 1
    if _state.count > 1:
        sys.stderr.write("\nedc-bench: interrupt noted; still bringing the rig to its safe state and writing the record\n")


def stop_requested() -> bool:
    """True once Ctrl-C or SIGTERM has arrived inside a guard, until the outermost guard ends."""
    return _state.count > 0


@contextmanager
def interrupt_guard(*, reraise: bool = True) -> Iterator[None]:
    """Within the block, Ctrl-C and SIGTERM request a stop (see :func:`stop_requested`) instead of raising.

    Parameters
    ----------
    reraise : bool
        At the end of the outermost guard, raise :class:`KeyboardInterrupt` if a signal came during it (the test
        has ended safely and its record is written by then): a caller that does not look at
        :func:`stop_requested` can never report an interrupted test as a whole one. False for the owner that
        says the interrupt itself (``edc-bench test``'s exit code 130 with its own words). A block that ends by
        an exception raises that one.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    if _state.depth == 0:
        _state.count = 0
        for sig in _SIGNALS:
            if signal.getsignal(sig) is not signal.SIG_IGN:
                _state.previous[sig] = signal.signal(sig, _handler)
    _state.depth += 1
    interrupted = False
    try:
        yield
    finally:
        _state.depth -= 1
        outermost = _state.depth == 0
        if outermost:
            for sig, previous in _state.previous.items():
                signal.signal(sig, signal.SIG_DFL if previous is None else previous)
            _state.previous = {}
            # said now or never: a stop request must not outlive its guard (a later session or test in this
            # process would end at once)
            interrupted, _state.count = _state.count > 0, 0
    if outermost and reraise and interrupted:
        raise KeyboardInterrupt


def _raise(signum: int, frame: object) -> None:
    if _state.settled:  # the command's outcome stands (written and said): the signal cannot change it
        _state.after_settled += 1
        return
    _state.raised = True
    raise KeyboardInterrupt


@contextmanager
def raise_on_interrupt() -> Iterator[None]:
    """Within the block, Ctrl-C and SIGTERM raise :class:`KeyboardInterrupt` (a service manager's stop, a
    shutdown, ``kill``: the same exit 130 as Ctrl-C, not a process killed mid-write), and
    :func:`interrupt_raised` says one did.

    Only in the main thread; a signal the parent process set to be ignored stays ignored. Guards inside the
    block (:func:`interrupt_guard`) hold both signals back as usual and put this back at their end.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    _state.raised = False
    _state.settled, _state.after_settled = False, 0
    was_raising, _state.raising = _state.raising, True
    previous = {sig: signal.signal(sig, _raise) for sig in _SIGNALS if signal.getsignal(sig) is not signal.SIG_IGN}
    previous_hook = sys.unraisablehook
    sys.unraisablehook = _raise_again
    try:
        yield
    finally:
        _state.raising = was_raising
        _state.settled = False
        sys.unraisablehook = previous_hook
        for sig, handler in previous.items():
            signal.signal(sig, signal.SIG_DFL if handler is None else handler)  # None: not set from Python


def _raise_again(unraisable: object) -> None:
    """Python ignores an exception raised where it cannot propagate (an import lock's callback, a destructor),
    printing a traceback: a Ctrl-C that lands there would be lost. Raise it again, as the signal it was, so that it
    reaches the command at its next step; anything else as Python would."""
    if isinstance(getattr(unraisable, "exc_value", None), KeyboardInterrupt):
        import os

        # sent again from another thread, once this hook has returned: raised here (raise_signal, interrupt_main run
        # the handler at once) it would be ignored again; the handler raises at the main thread's next step
        timer = threading.Timer(0.05, os.kill, args=(os.getpid(), signal.SIGINT))
        timer.daemon = True
        timer.start()
        return
    sys.__unraisablehook__(unraisable)  # type: ignore[arg-type]


def interrupt_raised() -> bool:
    """True once Ctrl-C or SIGTERM has raised :class:`KeyboardInterrupt` in a :func:`raise_on_interrupt` block
    (whatever a library made of it since)."""
    return _state.raised


def stop_if_interrupted() -> None:
    """Raise :class:`KeyboardInterrupt` if Ctrl-C or SIGTERM was raised in the :func:`raise_on_interrupt` block open
    now (none open: nothing to say; an earlier command's interrupt is not this caller's).

    Called by a command before it writes what long library work computed (a baseline, a model, a dataset): a
    library that caught the interrupt and ran on (a signal landing in code that swallows it) returns a result as
    if nothing happened, and the command would write it and only then exit 130.
    """
    if _state.raising and _state.raised:
        raise KeyboardInterrupt


def settle(*, raise_swallowed: bool = True) -> None:
    """The command's outcome is decided: say it now or say interrupted, never both.

    An interrupt raised before now that a library swallowed raises :class:`KeyboardInterrupt` here
    (:func:`stop_if_interrupted`: the caller removes what it wrote and the command exits 130, having announced
    nothing); from here to the end of the :func:`raise_on_interrupt` block, Ctrl-C and SIGTERM are noted
    (:func:`interrupted_after_settling`) and raise nothing, so a command that has written and is announcing its
    result is not then reported interrupted (its files and its words would contradict the exit code).

    Parameters
    ----------
    raise_swallowed : bool
        False for a command that has said its outcome already (``test``: its verdict, inside a guard that kept the
        interrupts as a stop request): only the signals to come are settled.
    """
    if raise_swallowed:
        stop_if_interrupted()
    if _state.raising:
        _state.settled = True


def interrupted_after_settling() -> int:
    """How many Ctrl-C or SIGTERM came after :func:`settle` in the open block (noted, not acted on)."""
    return _state.after_settled
