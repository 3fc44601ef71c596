"""How far the numbers behind a verdict hold (issue #37): the coverage study's arithmetic, its populations, and
the hardest valves' failures reproduced.

The slow tests at the end assert #37's done-when: a1 of a valve with more friction within 5 % (the estimate over the
core rows keeps Stribeck friction out of it), and the interval's holding the truth (it carries the misfit at
reversals and the baseline's own uncertainty).
"""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from edc_bench.config import load_variant
from edc_bench.experiments.coverage import (
    A1,
    AF,
    STICK_SLIP_FRICTION_FACTOR,
    STICK_SLIP_GAIN_VARIATION_REL,
    ShopBaseline,
    coverage_figures,
    coverage_populations,
    coverage_study,
    draw_sticky_valves,
    stick_slip_variant,
)
from edc_bench.physics.valve import ValveSpec
from edc_bench.population.batch import run_batch
from edc_bench.population.batch_stop import StopOutcome
from edc_bench.population.valves import draw_population
from edc_bench.verdict.baseline import Baseline
from edc_bench.verdict.classifier import default_classifier


def _outcome(features_rel, half_width_rel, trusted, certain) -> StopOutcome:
    out = StopOutcome(len(trusted))
    out.features_rel[:] = features_rel
    out.half_width_rel[:] = half_width_rel
    out.trusted[:] = trusted
    out.certain[:] = certain
    out.time_s[:] = 10.0
    return out


def test_coverage_figures_count_what_they_say() -> None:
    """Four valves whose answers are known: covered or not, within tolerance or not, untrusted, certain and wrong."""
    classifier = default_classifier()
    true_base = np.array([0.1, 0.002])
    shop = ShopBaseline(Baseline(af_v=0.101, a1_v_s_per_mm=0.002), true_base)  # af's baseline 1 % high
    true_rel = np.array([[1.0, 1.0], [1.2, 1.1], [1.0, 1.0], [2.5, 2.5]])
    truth = np.zeros((4, 6))
    truth[:, [AF, A1]] = true_rel * true_base
    parameters = truth.copy()
    parameters[:, AF] *= [1.01, 1.03, 1.0, 1.0]  # af 1 % off (within 2 %), 3 % off (not)
    parameters[:, A1] *= [0.98, 0.94, 1.0, 1.0]  # a1 2 % off (within 5 %), 6 % off (not)
    centre = np.array([[1.0, 1.0], [1.25, 1.1], [1.0, 1.0], [1.0, 1.0]])
    half = np.array([[0.01, 0.01], [0.02, 0.02], [0.5, 0.5], [0.01, 0.01]])
    stopped = _outcome(centre, half, trusted=[True, True, False, True], certain=[True, False, False, True])
    faulty = np.array([False, False, False, True])
    out = coverage_figures(stopped, parameters, truth, shop, classifier, faulty)
    assert out.judged == 3
    # valve 0 holds its truth, valve 1's af is 0.05 off with 0.02 either side, valve 3's 1.5 off
    assert out.af.covered == pytest.approx(1 / 3) and out.a1.covered == pytest.approx(2 / 3)
    assert out.af.within == pytest.approx(2 / 3) and out.a1.within == pytest.approx(2 / 3)
    assert out.af.baseline_error == pytest.approx(0.01)
    assert out.af.half_width_p50 == pytest.approx(0.01) and out.a1.half_width_p50 == pytest.approx(0.01)
    # valve 3 stopped certain of the verdict at (1, 1), a new valve's, while its truth is 2.5x a new one's
    assert out.certain == 2 and out.certain_wrong == 1
    assert out.faulty_passed == 1


def test_the_stick_slip_pump_has_stribeck_friction_and_a_gain_over_the_swing() -> None:
    base = load_variant("p-edc-default")
    pump = stick_slip_variant(base)
    swing_mm = sum(tone.amplitude_mm for tone in base.excitation.active_tones)
    assert pump.coil.force_constant_variation_per_mm * swing_mm == pytest.approx(STICK_SLIP_GAIN_VARIATION_REL)
    assert pump.valve.stribeck_velocity_mm_s > 0 and pump.valve.stiction_ratio > base.valve.stiction_ratio
    assert pump.pump.name == "p-edc-default-stick-slip"
    assert set(coverage_populations()) == {"default", "hard", "stick-slip"}


def test_sticky_valves_are_the_worn_ones_with_more_friction_only() -> None:
    variant = load_variant("p-edc-default")
    plain, sticky = draw_population(variant, 40, 3), draw_sticky_valves(variant, 40, 3)
    factors = np.array([s.friction_scale / p.friction_scale for p, s in zip(plain, sticky, strict=True)])
    assert np.all((factors >= STICK_SLIP_FRICTION_FACTOR[0]) & (factors <= STICK_SLIP_FRICTION_FACTOR[1]))
    assert factors.max() > 2.0  # the draw reaches well into the sticky range
    assert [(p.clearance_mm, p.damping_scale, p.coil_ohm) for p in plain] == \
        [(s.clearance_mm, s.damping_scale, s.coil_ohm) for s in sticky]


def test_coverage_on_the_command_line_refuses_an_unknown_population() -> None:
    run = subprocess.run([sys.executable, "-m", "edc_bench", "evaluate", "--coverage", "--populations", "sticky"],
                         capture_output=True, text=True, timeout=60)
    assert run.returncode == 2 and "invalid choice: 'sticky'" in run.stderr and "Traceback" not in run.stderr


def test_coverage_on_the_command_line_is_one_study_at_a_time() -> None:
    run = subprocess.run([sys.executable, "-m", "edc_bench", "evaluate", "--coverage", "--from-history"],
                         capture_output=True, text=True, timeout=60)
    assert run.returncode == 2 and "--coverage and --from-history are two different studies" in run.stderr
    assert "Traceback" not in run.stderr


@pytest.mark.slow  # 20-30 s
def test_coverage_on_the_command_line_prints_each_population() -> None:
    run = subprocess.run([sys.executable, "-m", "edc_bench", "evaluate", "--coverage", "--count", "8",
                          "--populations", "default", "hard", "--calibration-valves", "3"],
                         capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, run.stderr
    # each population with the model that judged it: the hard pump's own network
    for line in ("default (p-edc-default, judged by valve_mlp): ",
                 "hard (p-edc-hard, judged by valve_mlp-p-edc-hard): ", "interval covers the truth", "stopped certain"):
        assert line in run.stdout


# ------------------------------------------------------------------------- #37's done-when


@pytest.mark.slow  # 10 s each
@pytest.mark.parametrize(("pump_name", "friction"), [("stick-slip", 3.0), ("hard", 2.0)])
def test_a1_of_a_new_valve_with_more_friction_is_within_5_percent(pump_name: str, friction: float) -> None:
    """#37 item 1: high friction no longer leaks into a1. The fit over every used row reads a1 far lower (the core
    shift: stick windows and Stribeck peaks smoothed into rows read as sliding); the estimate, over the core rows,
    does not (it read -7.2 % and -9.1 % when the estimate was the fit over every row)."""
    pump = coverage_populations()[pump_name].variant
    result = run_batch(pump, [ValveSpec(pump.valve.clearance_new_mm, friction_scale=friction)], [0])
    error = result.parameters[0] / result.truth[0] - 1.0
    shift_a1 = float(result.periods.at(result.periods.blocks).fit.relative_figures("a1")[1][0])
    print(f"{pump_name}, {friction:g}x friction: af {error[AF]:+.2%}, a1 {error[A1]:+.2%}, a1's core shift "
          f"{shift_a1:+.2%}")
    assert result.trusted[0]
    assert shift_a1 < -0.05  # what the estimate keeps out
    assert abs(error[AF]) <= 0.02 and abs(error[A1]) <= 0.05, f"af {error[AF]:+.1%}, a1 {error[A1]:+.1%}"


@pytest.mark.slow  # 20 s
def test_the_99_percent_interval_holds_the_truth_for_95_percent_of_sticky_valves() -> None:
    out = coverage_study(coverage_populations()["stick-slip"], default_classifier(), 60, 777, 5)
    assert out.certain_wrong == 0
    assert out.af.covered >= 0.95 and out.a1.covered >= 0.95, (out.af, out.a1)
