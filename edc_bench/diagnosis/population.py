"""Simulated valve populations and their ground truth.

Wear (plunger clearance) is drawn uniformly over the variant's range; a share
of valves is unevenly worn (roughness above 1, like the paper's valve V3);
each valve gets the variant's spread in friction and damping. The label
(faulty or not) comes from the valve's physics and the variant's limit,
never from identified parameters.
"""

from __future__ import annotations

import numpy as np

from edc_bench.config.models import Variant
from edc_bench.physics.valve import ValveSpec, sample_valve


def draw_population(variant: Variant, count: int, seed: int) -> list[ValveSpec]:
    """``count`` used valves of a variant, reproducible from ``seed``.

    Parameters
    ----------
    variant : Variant
        Supplies the population ranges and the spread between valves.
    count : int
        Number of valves.
    seed : int
        Seed of the draw.
    """
    pop = variant.diagnosis.population
    rng = np.random.default_rng(seed)
    valves = []
    for n in range(count):
        clearance = float(rng.uniform(pop.clearance_min_mm, pop.clearance_max_mm))
        rough = rng.random() < pop.rough_fraction
        roughness = float(rng.uniform(1.0, pop.roughness_max)) if rough else 1.0
        valves.append(sample_valve(variant, clearance, rng, roughness, label=f"{variant.name}-{seed}-{n}"))
    return valves


def new_valves(variant: Variant, count: int, seed: int) -> list[ValveSpec]:
    """``count`` new valves (the ``new`` preset's clearance) with the spread between valves."""
    preset = variant.valve.presets["new"]
    rng = np.random.default_rng(seed)
    return [sample_valve(variant, preset.clearance_mm, rng, preset.roughness, label=f"new-{seed}-{n}")
            for n in range(count)]
