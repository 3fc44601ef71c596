"""`edc-bench tune`'s search: gains that keep the margins with the most bandwidth (python-control)."""

from __future__ import annotations

import dataclasses

import pytest
from helpers import write_new_pump_type

from edc_bench.config import load_variant
from edc_bench.control.pid import PidGains
from edc_bench.control.stability import loop_margins
from edc_bench.control.tuning import step_figures, tune_pid
from edc_bench.errors import ConfigError
from edc_bench.physics.valve import nominal_plant
from edc_bench.engine.replies import max_reply_age_ticks


def _present(variant):
    c = variant.controller
    return PidGains(c.kp_v_per_mm, c.ki_v_per_mm_s, c.kd_v_s_per_mm, c.derivative_filter_hz)


@pytest.mark.slow  # 4 s: CI's slow pass (the default suite stays under 5 minutes)
def test_gains_for_a_pump_with_twice_the_force_constant_keep_the_margins(tmp_path) -> None:
    variant = load_variant(write_new_pump_type(tmp_path))
    plant, period, delay = nominal_plant(variant), variant.controller.period_s, max_reply_age_ticks(variant)
    before = loop_margins(plant, *dataclasses.astuple(_present(variant)), period, delay)
    assert before.gain_margin_db < 6 or before.phase_margin_deg < 30  # the default's gains do not fit it
    tuned = tune_pid(plant, period, delay, 6.0, 30.0)
    again = loop_margins(plant, *dataclasses.astuple(tuned.gains), period, delay)  # checked anew, as the bench will
    assert again.closed_loop_stable
    assert again.gain_margin_db >= 6.0 and again.phase_margin_deg >= 30.0
    assert again == tuned.margins
    assert 0 < tuned.settling_s < 0.5 and tuned.closed_loop_bandwidth_hz > 5.0


# the other variants in CI's slow pass: the default suite stays under 5 minutes
@pytest.mark.parametrize("name", ["p-edc-default", pytest.param("p-edc-long", marks=pytest.mark.slow),
                                  pytest.param("paper", marks=pytest.mark.slow)])
def test_proposed_gains_follow_at_least_as_fast_as_the_hand_tuned_ones(name: str) -> None:
    variant = load_variant(name)
    plant, period, delay = nominal_plant(variant), variant.controller.period_s, max_reply_age_ticks(variant)
    tuned = tune_pid(plant, period, delay, variant.controller.min_gain_margin_db,
                     variant.controller.min_phase_margin_deg)
    shipped_bandwidth_hz, _, _ = step_figures(plant, _present(variant), period, delay)
    assert tuned.margins.gain_margin_db >= variant.controller.min_gain_margin_db
    assert tuned.margins.phase_margin_deg >= variant.controller.min_phase_margin_deg
    assert tuned.closed_loop_bandwidth_hz >= 0.95 * shipped_bandwidth_hz


@pytest.mark.slow  # seconds: CI's slow pass runs it (the default suite stays under 5 minutes on CI)
def test_margins_no_pid_can_keep_are_refused_with_what_to_change() -> None:
    variant = load_variant("p-edc-default")
    with pytest.raises(ConfigError, match=r"no PID gains keep 60 dB and 30 deg .* 4 ticks of transport delay"):
        tune_pid(nominal_plant(variant), 0.001, 4, 60.0, 30.0)


@pytest.mark.slow  # 4.5 s, as above
def test_a_slow_adapter_gets_integral_dominated_gains() -> None:
    # 15 ms of reply age: only a PI whose integral corner lies above the crossover keeps the margins
    from edc_bench.config import with_changes

    variant = with_changes(load_variant("p-edc-default"), {"acceptance": {"max_reply_age_ms": 15.0}}, "a test")
    tuned = tune_pid(nominal_plant(variant), 0.001, max_reply_age_ticks(variant), 6.0, 30.0)
    assert tuned.margins.closed_loop_stable and tuned.margins.delay_ticks == 15
    assert tuned.margins.gain_margin_db >= 6.0 and tuned.margins.phase_margin_deg >= 30.0
