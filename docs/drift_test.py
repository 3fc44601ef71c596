"""Print the figures of docs/method.md section 7, "The noise allowance": ``python docs/drift_test.py``.

How often the drift test (edc_bench.identification.period_fit.drift_free, settle band 2 %) calls white noise drifting,
how often it catches drifts of several shapes, and where its statistic lies on the real scatter of 200 p-edc-hard
valves through the simulated USB full-speed adapter (30 s, batch path). About two minutes.
"""

from __future__ import annotations

import numpy as np

from edc_bench.config import load_variant
from edc_bench.identification.period_fit import DRIFT_CRITICAL, drift_free, drift_statistic
from edc_bench.population.batch import run_batch
from edc_bench.population.valves import draw_population
from edc_bench.sim.adapter import parse_adapter

BAND_REL = 0.02


def shapes(periods: int) -> dict[str, np.ndarray]:
    k = np.arange(periods)
    return {"step at the middle": (k >= periods // 2) * 1.0, "step at a third": (k >= periods // 3) * 1.0,
            "step at a quarter": (k >= periods // 4) * 1.0, "steady": k / (periods - 1),
            "transient halving each period": 1.0 - 0.5 ** k}


def main() -> None:
    rng = np.random.default_rng(2026)
    print("noise alone called drifting (100 000 tests each):")
    for periods in (8, 14, 30):
        for scatter in (0.01, 0.04, 0.10):
            y = 1.0 + scatter * rng.normal(size=(periods, 100_000))
            drifting = 1 - drift_free(y, np.ones(100_000), BAND_REL).mean()
            print(f"  {periods} periods, scatter {scatter:.0%} a period: {drifting:.2%}")
    print("drifts caught (4 000 tests each), by the drift's size over the test and the scatter a period:")
    for periods in (8, 14):
        for name, shape in shapes(periods).items():
            cells = []
            for size in (0.05, 0.10, 0.5):
                for scatter in (0.0, 0.01):
                    y = 1.0 + size * shape[:, None] + scatter * rng.normal(size=(periods, 4000))
                    cells.append(f"{size:.0%}/{scatter:.0%}: {1 - drift_free(y, y.mean(axis=0), BAND_REL).mean():.0%}")
            print(f"  {periods} periods, {name}: " + ", ".join(cells))
    variant = load_variant("p-edc-hard")
    valves = draw_population(variant, 200, seed=12)  # the population of tests/population/test_latency.py
    result = run_batch(variant, valves, list(range(5000, 5200)), adapter=parse_adapter("usb-fs"))
    fit = result.periods.at(result.periods.blocks).fit
    limit = np.interp(fit.blocks, *zip(*DRIFT_CRITICAL))
    print(f"200 p-edc-hard valves through usb-fs, {fit.blocks} periods (limit {limit:.2f}):")
    for name in ("af", "a1"):
        i = fit.columns.index(name)
        statistic = drift_statistic(fit.block_theta[:, :, i])
        print(f"  {name}: statistic's 99th percentile {np.percentile(statistic, 99):.2f}, "
              f"largest {statistic.max():.2f}; converged {int(result.converged.sum())} of 200")


if __name__ == "__main__":
    main()
