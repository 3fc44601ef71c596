"""A rig that is a process on this PC and stops answering is the PC's doing, not a cable's.

The tester's finding: the README's two-terminal example (``edc-bench rig --listen`` in one terminal, ``test
--realtime --interface slcan ...`` in the other) ended INVALID 4 of 4 on a busy machine, "the rig stopped
answering", advice "check the CAN cable and termination": for a simulated rig on the same PC there is no cable.
Here the rig falls silent in simulated time (its replies stop; the bench's own ticks are on time, so the bench's
stall check sees nothing), once with the rig on this PC and once on a bus.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from edc_bench.bench import run_simulated_test
from edc_bench.config.models import Variant
from edc_bench.engine.outcome import AbortKind
from edc_bench.engine.problems import Problem
from edc_bench.records.advice import Cause
from edc_bench.records.reader import load_record
from edc_bench.records.record import write_record
from edc_bench.replay import replay_record
from edc_bench.runtime.bus_config import BusSettings, rig_on_this_pc
from edc_bench.runtime.clock import Clock


class RigFallsSilent(Clock):
    """The inner clock, with the rig no longer served (it answers nothing) from ``silent_from_s`` on."""

    def __init__(self, inner: Clock, silent_from_s: float) -> None:
        self.inner, self.silent_from_s = inner, silent_from_s
        self.waits_for_replies, self.kind = inner.waits_for_replies, inner.kind

    def start(self) -> None:
        self.inner.start()

    def now_s(self) -> float:
        return self.inner.now_s()

    def wait_until(self, t_s: float) -> float:
        return self.inner.wait_until(t_s)

    def after_send(self, t_s: float) -> None:
        if self.inner.now_s() < self.silent_from_s:
            self.inner.after_send(t_s)


def _silent_rig_test(variant: Variant, on_this_pc: bool) -> object:
    return run_simulated_test(variant, "new", seed=1, clock_wrapper=lambda c: RigFallsSilent(c, 3.0),
                              rig_on_this_pc=on_this_pc)


def test_a_silent_rig_on_this_pc_names_the_pc_not_the_cable(variant: Variant, tmp_path: Path) -> None:
    result = _silent_rig_test(variant, on_this_pc=True)
    assert result.outcome.abort is not None and result.outcome.abort.kind is AbortKind.SILENCE
    assert Problem.PC_STALLED in result.judgement.problems
    assert any("the rig is a process on this PC and stopped answering in time" in r for r in result.reasons)
    assert result.advice.words.startswith("not judged: the PC stalled")
    assert "cable" not in result.advice.words
    folder = write_record(result, tmp_path, figure=False)
    record = load_record(folder)
    assert record.timing.rig_on_this_pc is True
    assert record.advice == result.advice and record.invalid_cause is Cause.BENCH
    report = replay_record(folder)
    assert report.reproduced, report.differences


def test_the_same_silence_from_a_rig_on_a_bus_still_says_check_the_rig(variant: Variant) -> None:
    result = _silent_rig_test(variant, on_this_pc=False)
    assert result.outcome.abort is not None and result.outcome.abort.kind is AbortKind.SILENCE
    assert Problem.PC_STALLED not in result.judgement.problems
    assert "the CAN cable and termination" in result.advice.words


@pytest.mark.parametrize(("settings", "here"), [
    ({"interface": "slcan", "channel": "socket://127.0.0.1:5000"}, True),
    ({"interface": "slcan", "channel": "socket://localhost:5000"}, True),
    ({"interface": "slcan", "channel": "socket://[::1]:5000"}, True),
    ({"interface": "slcan", "channel": "/dev/pts/4"}, True),
    ({"interface": "slcan", "channel": "socket://192.168.1.20:5000"}, False),
    ({"interface": "slcan", "channel": "/dev/ttyACM0"}, False),
    ({"interface": "socketcan", "channel": "can0"}, False),
])
def test_a_rig_is_on_this_pc_over_loopback_or_a_pseudo_terminal(settings: dict[str, str], here: bool) -> None:
    assert rig_on_this_pc(BusSettings(settings)) is here
