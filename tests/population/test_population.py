"""Populations of simulated valves: seeded, labelled by physics."""

from __future__ import annotations

import numpy as np

from edc_bench.config import load_variant
from edc_bench.physics.valve import parse_valve_spec
from edc_bench.physics.wear import is_faulty, resisting_force_n
from edc_bench.population.valves import draw_population, new_valves


def test_labels_come_from_physics() -> None:
    variant = load_variant()
    valves = draw_population(variant, 200, 5)
    assert valves == draw_population(variant, 200, 5)
    labels = np.array([is_faulty(variant, v) for v in valves])
    forces = np.array([resisting_force_n(variant, v) for v in valves])
    assert np.array_equal(labels, forces > variant.diagnosis.resistance_limit_n)
    assert 0.3 < labels.mean() < 0.8  # both classes well represented
    assert not any(is_faulty(variant, v) for v in new_valves(variant, 20, 1))
    assert is_faulty(variant, parse_valve_spec("worn", variant)) and is_faulty(variant, parse_valve_spec("faulty", variant))
