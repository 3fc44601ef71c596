"""#54's bug from asking a clock's class: a simulated test behind a wrapped clock (host stalls injected) was
recorded as "real-time" and told the technician its baseline was "measured in simulation, not on a rig". A clock
now says its kind, and a wrapper passes its inner clock's on."""

from __future__ import annotations

from pathlib import Path

from edc_bench.bench import run_simulated_test
from edc_bench.config import load_variant
from edc_bench.records.reader import load_record
from edc_bench.records.record import write_record
from edc_bench.runtime.clock import RealTimeClock, SimulatedClock
from edc_bench.runtime.clock_kind import ClockKind
from edc_bench.testing.stalls import StallingClock


def test_every_clock_says_its_kind_and_a_wrapper_its_inner_clocks() -> None:
    assert SimulatedClock().kind is ClockKind.SIMULATED
    assert RealTimeClock().kind is ClockKind.REAL_TIME
    assert StallingClock(SimulatedClock(), 0.005, 1.0).kind is ClockKind.SIMULATED
    assert StallingClock(RealTimeClock(), 0.005, 1.0).kind is ClockKind.REAL_TIME


def test_a_simulated_test_with_host_stalls_is_recorded_as_simulated_time(tmp_path: Path) -> None:
    result = run_simulated_test(load_variant(), "new", 3,
                                clock_wrapper=lambda clock: StallingClock(clock, 0.005, 1.0, first_s=2.5))
    assert result.clock == "simulated"
    assert not any("measured in simulation" in reason for reason in result.reasons), result.reasons
    record = load_record(write_record(result, tmp_path, figure=False))
    assert record.clock == "simulated" and not record.real_time
