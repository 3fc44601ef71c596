"""Baseline calibration: the mean af and a1 of converged new-valve tests, with their spread."""

from __future__ import annotations

import math

import numpy as np

from edc_bench.config.models import Variant
from edc_bench.population.batch import BatchResult, run_batch
from edc_bench.population.valves import new_valves
from edc_bench.config.models import PARAMETER_NAMES
from edc_bench.verdict.baseline import MOTION_KEYS, MOTION_PARAMETERS, UNCERTAINTY_KEYS, BaselineTest
from edc_bench.verdict.baseline_source import BaselineSource


def population_run(variant: Variant, tests: int, seed: int) -> tuple[list[BaselineTest], BatchResult]:
    """The converged tests of ``tests`` simulated new valves (each with the variant's spread between valves), and
    the batch run they come from (its ``truth`` and ``trusted`` too, for studies that compare with the plant).

    Only trusted tests count (the trust rule, :mod:`edc_bench.identification.trust`), as on a real rig. The batch path
    writes no records.
    """
    valves = new_valves(variant, tests, seed)
    result = run_batch(variant, valves, [seed * 100_000 + n for n in range(tests)])
    af, a1 = result.feature("af"), result.feature("a1")
    assert result.periods is not None  # a full-length batch keeps its period fit
    fit = result.periods.at(result.periods.blocks).fit
    figures = np.full((len(UNCERTAINTY_KEYS), tests), np.nan)
    if fit is not None:
        (figures[0], figures[2]), (figures[1], figures[3]) = fit.relative_figures("af"), fit.relative_figures("a1")
        figures[4] = fit.systematic_rms_v
    motion = {key: result.parameters[:, PARAMETER_NAMES.index(MOTION_PARAMETERS[key])] for key in MOTION_KEYS}
    kept = [BaselineTest(float(af[n]), float(a1[n]), valve_id=f"{valves[n].label} (seed {seed})",
                         source=BaselineSource.SIMULATED_POPULATION,
                         **_known(dict(zip(UNCERTAINTY_KEYS, figures[:, n]))),
                         **_known({key: float(values[n]) for key, values in motion.items()}))
            for n in range(tests) if result.trusted[n]]
    return kept, result


def _known(figures: dict[str, float]) -> dict[str, float | None]:
    """The figures as a test keeps them: None where not known."""
    return {key: float(value) if math.isfinite(value) else None for key, value in figures.items()}


def population_tests(variant: Variant, tests: int, seed: int) -> list[BaselineTest]:
    """The converged tests of ``tests`` simulated new valves (:func:`population_run`)."""
    return population_run(variant, tests, seed)[0]
