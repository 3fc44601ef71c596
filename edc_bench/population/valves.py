"""Simulated valve populations and their ground truth.

Wear (plunger clearance) is drawn uniformly over the variant's range; a share
of valves is unevenly worn (roughness above 1, like the paper's valve V3);
each valve gets the variant's spread in friction and damping. Its coil is
drawn too, from a stream of its own (so the valves' wear is the same with
or without it): a resistance uniform over the variant's coil spec and a
temperature at the start of the test uniform over the population's range
(a coil cold from the shelf up to one warm from earlier tests). The label
(faulty or not) comes from the valve's physics and the variant's limit,
never from identified parameters, and never from the coil.
"""

from __future__ import annotations

from dataclasses import replace

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
    return with_coils(variant, valves, seed)


def with_coils(variant: Variant, valves: list[ValveSpec], seed: int) -> list[ValveSpec]:
    """The valves with coils drawn over the variant's coil spec and the population's coil temperatures.

    Without a coil spec in the variant, every coil is the nominal one; the temperatures are drawn all the same.
    """
    coil, pop = variant.coil, variant.diagnosis.population
    rng = np.random.default_rng([seed, 0xC011])
    low = coil.resistance_min_ohm if coil.resistance_min_ohm is not None else coil.resistance_ohm
    high = coil.resistance_max_ohm if coil.resistance_max_ohm is not None else coil.resistance_ohm
    ohms = rng.uniform(low, high, len(valves))
    temps = rng.uniform(pop.coil_temp_min_c, pop.coil_temp_max_c, len(valves))
    return [replace(v, coil_ohm=float(r), coil_temp_c=float(t)) for v, r, t in zip(valves, ohms, temps, strict=True)]


def new_valves(variant: Variant, count: int, seed: int) -> list[ValveSpec]:
    """``count`` new valves (the ``new`` preset's clearance) with the spread between valves, and coils drawn."""
    preset = variant.valve.presets["new"]
    rng = np.random.default_rng(seed)
    valves = [sample_valve(variant, preset.clearance_mm, rng, preset.roughness, label=f"new-{seed}-{n}")
              for n in range(count)]
    return with_coils(variant, valves, seed)
