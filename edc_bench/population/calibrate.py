"""Baseline calibration: the mean af and a1 of converged new-valve tests, with their spread."""

from __future__ import annotations

from edc_bench.config.models import Variant
from edc_bench.population.batch import BatchResult, run_batch
from edc_bench.population.valves import new_valves
from edc_bench.verdict.baseline import BaselineTest

SIMULATED_POPULATION = "simulated population"


def population_run(variant: Variant, tests: int, seed: int) -> tuple[list[BaselineTest], BatchResult]:
    """The converged tests of ``tests`` simulated new valves (each with the variant's spread between valves), and
    the batch run they come from (its ``truth`` and ``trusted`` too, for studies that compare with the plant).

    Only trusted tests count (the trust rule, :mod:`edc_bench.identification.trust`), as on a real rig. The batch path
    writes no records.
    """
    valves = new_valves(variant, tests, seed)
    result = run_batch(variant, valves, [seed * 100_000 + n for n in range(tests)])
    af, a1 = result.feature("af"), result.feature("a1")
    kept = [BaselineTest(float(af[n]), float(a1[n]), valve_id=f"{valves[n].label} (seed {seed})",
                         source=SIMULATED_POPULATION)
            for n in range(tests) if result.trusted[n]]
    return kept, result


def population_tests(variant: Variant, tests: int, seed: int) -> list[BaselineTest]:
    """The converged tests of ``tests`` simulated new valves (:func:`population_run`)."""
    return population_run(variant, tests, seed)[0]
