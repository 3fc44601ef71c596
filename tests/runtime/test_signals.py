"""The interrupt guard and the CLI's handlers, in process: Ctrl-C and SIGTERM alike, held back inside a guard and
raised at its end unless its owner says the interrupt itself (#52)."""

from __future__ import annotations

import os
import signal
import time

import pytest

from edc_bench.runtime.signals import interrupt_guard, interrupt_raised, raise_on_interrupt, stop_requested


def _signal_self(sig: int) -> None:
    """Send ``sig`` to this process and give Python the moment to run its handler."""
    os.kill(os.getpid(), sig)
    for _ in range(100):  # the handler runs between bytecodes of the main thread: at once, in practice
        time.sleep(0.001)


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_a_guard_holds_the_signal_back_then_raises_it_at_its_end(sig: int) -> None:
    with pytest.raises(KeyboardInterrupt):
        with interrupt_guard():
            with interrupt_guard():  # the inner guard's end raises nothing: the outer one's work goes on
                _signal_self(sig)
                assert stop_requested()
            reached = True
    assert reached


def test_the_owner_of_a_guard_may_say_the_interrupt_itself() -> None:
    with interrupt_guard(reraise=False):
        _signal_self(signal.SIGINT)
        seen = stop_requested()
    assert seen


def test_an_error_in_the_block_is_raised_rather_than_the_interrupt() -> None:
    with pytest.raises(ValueError):
        with interrupt_guard():
            _signal_self(signal.SIGTERM)
            raise ValueError("the block's own")


def test_a_guard_puts_the_handlers_back() -> None:
    before = {sig: signal.getsignal(sig) for sig in (signal.SIGINT, signal.SIGTERM)}
    with interrupt_guard(reraise=False):
        pass
    assert {sig: signal.getsignal(sig) for sig in before} == before


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_outside_a_guard_both_signals_raise_and_are_noted(sig: int) -> None:
    before = signal.getsignal(signal.SIGTERM)
    with pytest.raises(KeyboardInterrupt):
        with raise_on_interrupt():
            assert not interrupt_raised()
            _signal_self(sig)
    assert interrupt_raised()  # what a library made of the KeyboardInterrupt is still the operator's interrupt
    assert signal.getsignal(signal.SIGTERM) == before


def test_an_ignored_signal_stays_ignored() -> None:
    previous = signal.signal(signal.SIGTERM, signal.SIG_IGN)  # nohup, a parent that ignores it for its children
    try:
        with raise_on_interrupt(), interrupt_guard(reraise=False):
            _signal_self(signal.SIGTERM)
            assert not stop_requested()
        assert signal.getsignal(signal.SIGTERM) is signal.SIG_IGN
    finally:
        signal.signal(signal.SIGTERM, previous)


_LOST_CTRL_C = """
import gc, sys, time, weakref
from edc_bench.runtime.signals import raise_on_interrupt

class Thing:
    pass

def callback(_):
    raise KeyboardInterrupt  # as the signal's handler raises it, in a place Python cannot let it out of

try:
    with raise_on_interrupt():
        thing = Thing()
        ref = weakref.ref(thing, callback)
        del thing
        gc.collect()
        deadline = time.monotonic() + 30
        while time.monotonic() < deadline:
            time.sleep(0.01)
except KeyboardInterrupt:
    print("raised again")
    sys.exit(0)
print("lost")
sys.exit(1)
"""


def test_a_ctrl_c_python_would_ignore_is_raised_again() -> None:
    """A KeyboardInterrupt raised where Python cannot let it propagate (a weakref's callback here, an import
    lock's in the CI run that found it) is not lost: it reaches the code after it.

    In a process of its own, as a command meets it: in the suite's worker, which has run a thousand tests (servers,
    threads, a browser's driver), the signal sent again was not seen within 30 s in one full run in three (twice,
    on CI and here), though no test left a handler or a guard behind."""
    import subprocess
    import sys

    done = subprocess.run([sys.executable, "-c", _LOST_CTRL_C], capture_output=True, text=True, timeout=60)
    assert done.returncode == 0 and done.stdout.strip() == "raised again", (done.stdout, done.stderr)
    assert "Exception ignored" not in done.stderr  # not printed and dropped as Python would


def test_a_stop_request_does_not_outlive_its_guard() -> None:
    """A SIGTERM held back by one session's guard made the next session in the same process (CI's worker running
    the next test) end before its first test."""
    import os

    from edc_bench.runtime.signals import interrupt_guard, stop_requested

    with interrupt_guard(reraise=False):
        os.kill(os.getpid(), signal.SIGTERM)
        while not stop_requested():  # the handler runs at the main thread's next step
            pass
        assert stop_requested()
    assert not stop_requested()
    with pytest.raises(KeyboardInterrupt):
        with interrupt_guard():
            os.kill(os.getpid(), signal.SIGTERM)
            while not stop_requested():
                pass
    assert not stop_requested()


def test_stop_if_interrupted_speaks_only_inside_the_block_that_was_interrupted() -> None:
    """A command's writer asks before writing (stop_if_interrupted); after the interrupted block has ended, a later
    caller in the same process (a library function called outside a command) is not stopped by it."""
    from edc_bench.runtime.signals import stop_if_interrupted

    with pytest.raises(KeyboardInterrupt):
        with raise_on_interrupt():
            stop_if_interrupted()  # nothing raised yet
            try:
                _signal_self(signal.SIGINT)
            except KeyboardInterrupt:
                pass  # a library swallows it
            stop_if_interrupted()  # the command asks: still Ctrl-C
    assert interrupt_raised()
    stop_if_interrupted()  # the block is over: nothing to say
