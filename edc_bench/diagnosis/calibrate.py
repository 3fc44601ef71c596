"""Baseline calibration: the mean af and a1 of new valves, with their spread."""

from __future__ import annotations

import numpy as np

from edc_bench.config.models import Variant
from edc_bench.diagnosis.baseline import Baseline
from edc_bench.diagnosis.batch import run_batch
from edc_bench.diagnosis.population import new_valves
from edc_bench.errors import EdcBenchError


def baseline_from_features(af: np.ndarray, a1: np.ndarray, source: str) -> Baseline:
    """A baseline from the features of several new-valve tests.

    Raises
    ------
    EdcBenchError
        With fewer than two tests.
    """
    af, a1 = np.asarray(af, float), np.asarray(a1, float)
    if len(af) < 2:
        raise EdcBenchError("a baseline needs at least two converged new-valve tests")
    return Baseline(float(af.mean()), float(a1.mean()), float(af.std(ddof=1)), float(a1.std(ddof=1)),
                    int(len(af)), source)


def calibrate_simulated(variant: Variant, tests: int, seed: int) -> Baseline:
    """Calibrate on ``tests`` simulated new valves (with the spread between valves).

    Only converged tests count, as on a real rig.
    """
    valves = new_valves(variant, tests, seed)
    result = run_batch(variant, valves, [seed * 100_000 + n for n in range(tests)])
    ok = result.converged
    return baseline_from_features(result.feature("af")[ok], result.feature("a1")[ok],
                                  f"simulated rig: {int(ok.sum())} new valves, seed {seed}")
