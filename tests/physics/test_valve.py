"""Valves: spec parsing, wear mapping, spread, and the true feedforward parameters."""

from __future__ import annotations

import numpy as np
import pytest

from edc_bench.config import Variant
from edc_bench.errors import ConfigError
from edc_bench.physics.feedforward import feedforward_truth
from edc_bench.physics.valve import ValveSpec, parse_valve_spec, plant_parameters, sample_valve


def test_presets_and_physical_specs(variant: Variant) -> None:
    assert parse_valve_spec("new", variant).clearance_mm == variant.valve.presets["new"].clearance_mm
    faulty = parse_valve_spec("faulty", variant)
    assert faulty.roughness == variant.valve.presets["faulty"].roughness
    spec = parse_valve_spec("clearance=0.22, roughness=1.5", variant)
    assert (spec.clearance_mm, spec.roughness) == (0.22, 1.5)
    assert parse_valve_spec("worn,roughness=1.2", variant).roughness == 1.2


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ("broken", r"unknown valve 'broken'; use one of faulty, new, worn"),
        ("clearance=abc", r"clearance = 'abc' is not a number"),
        ("clearance=-0.1", r"must be a positive number"),
        ("clearance=nan", r"must be a positive number"),
        ("roughness=2", r"give a preset .* or clearance=MM"),
        ("colour=red", r"unknown key 'colour'"),
        ("clearance=5", r"not plausible"),
    ],
)
def test_bad_valve_specs_are_refused(variant: Variant, text: str, match: str) -> None:
    with pytest.raises(ConfigError, match=match):
        parse_valve_spec(text, variant)


def test_truth_matches_design_formulas(variant: Variant) -> None:
    p = plant_parameters(variant, parse_valve_spec("worn", variant))
    gain = p.amplifier_gain * p.force_constant_n_per_a
    m = p.mass_kg * 1e-3
    k_net = p.spring_n_per_mm - p.magnetic_stiffness_n_per_mm
    truth = feedforward_truth(p)
    assert truth.a3 == pytest.approx(p.inductance_h * m / gain)
    assert truth.a2 == pytest.approx((m * p.resistance_ohm + p.inductance_h * p.damping_n_s_per_mm) / gain)
    assert truth.a1 == pytest.approx((p.inductance_h * k_net + p.resistance_ohm * p.damping_n_s_per_mm) / gain)
    assert truth.a0 == pytest.approx(p.resistance_ohm * k_net / gain)
    assert truth.b == pytest.approx(p.resistance_ohm * p.preload_n / gain)
    assert truth.af == pytest.approx(p.resistance_ohm * p.coulomb_friction_n / gain)
    # u1 with the truth holds the rack still at x: a0 x + b must be the static drive
    assert truth.a0 * 10.0 + truth.b == pytest.approx(p.drive_for_position_v(10.0))


def test_wear_raises_af_and_a1_monotonically(any_variant: Variant) -> None:
    clearances = np.linspace(any_variant.valve.clearance_new_mm, 0.35, 8)
    truths = [feedforward_truth(plant_parameters(any_variant, ValveSpec(c))) for c in clearances]
    assert all(b.af > a.af for a, b in zip(truths, truths[1:], strict=False))
    assert all(b.a1 > a.a1 for a, b in zip(truths, truths[1:], strict=False))
    # wear leaves the stiffness, mass and preload terms alone
    assert len({round(t.a0, 12) for t in truths}) == 1
    assert len({round(t.b, 12) for t in truths}) == 1


def test_presets_order_like_the_paper(any_variant: Variant) -> None:
    new, worn, faulty = (feedforward_truth(plant_parameters(any_variant, parse_valve_spec(n, any_variant)))
                         for n in ("new", "worn", "faulty"))
    assert new.af < worn.af < faulty.af
    assert new.a1 < worn.a1 < faulty.a1
    assert 0.3 < worn.af / new.af - 1 < 0.8  # paper's V2: +52 %


def test_spread_between_valves_is_seeded(variant: Variant) -> None:
    a = sample_valve(variant, 0.2, np.random.default_rng(5))
    b = sample_valve(variant, 0.2, np.random.default_rng(5))
    c = sample_valve(variant, 0.2, np.random.default_rng(6))
    assert a == b and a != c
    scales = [sample_valve(variant, 0.2, np.random.default_rng(s)).friction_scale for s in range(400)]
    assert np.std(np.log(scales)) == pytest.approx(variant.valve.spread_rel, rel=0.15)
