"""A simulated shop: valves tested, judged and torn down, in a history, to show what the shop's labels teach.

The shop's scrap limit is stricter than the one the shipped models learnt
(it replaces valves whose resisting force exceeds ``scrap_factor`` times
the variant's limit): valves between the two limits pass the bench but the
shop, opening them, finds them worn. Each valve is tested once through the
batch path (the same identification as the loop), judged by the station's
model against the shipped simulated baseline, and torn down the next day.
The tests are rows in the history (no record folders: their ``record_dir``
says ``simulated-shop:``), the findings are teardown labels.

Run it, then train and compare::

    python -m edc_bench.history.simulated_shop --db sqlite:///shop.sqlite --count 300
    edc-bench train --from-history --db sqlite:///shop.sqlite
"""

from __future__ import annotations

import argparse
import datetime as dt
import os
import sys
from collections.abc import Sequence
from typing import Any

import numpy as np

from edc_bench.config import load_variant
from edc_bench.history.secrets import shown_url
from edc_bench.history.store import HistoryStore
from edc_bench.learning.dataset import run_population
from edc_bench.physics.wear import resisting_force_n
from edc_bench.population.valves import draw_population
from edc_bench.verdict.baseline import load_baseline
from edc_bench.verdict.classifier import default_classifier
from edc_bench.verdict.verdicts import Verdict

SHOP_START = dt.datetime(2026, 1, 5, 8, 0, tzinfo=dt.UTC)
DEFAULT_SCRAP_FACTOR = 0.85


def simulate_shop(store: HistoryStore, count: int, seed: int, *, scrap_factor: float = DEFAULT_SCRAP_FACTOR,
                  variants: Sequence[str] = ("p-edc-default", "p-edc-long"),
                  workers: int | None = None) -> dict[str, Any]:
    """Test ``count`` valves (split over ``variants``), judge them, tear them down; all into ``store``.

    Returns counts: tests, labelled, worn by the shop's limit, worn by the variant's limit, INVALID.
    """
    if count < 1 or not 0 < scrap_factor <= 1.5:
        raise ValueError("count must be at least 1 and scrap_factor in (0, 1.5]")
    workers = workers or os.cpu_count() or 1
    counts = {"tests": 0, "labelled": 0, "worn_by_shop": 0, "worn_by_variant": 0, "invalid": 0}
    index = 0
    for v_index, name in enumerate(variants):
        variant = load_variant(name)
        n = count // len(variants) + (1 if v_index < count % len(variants) else 0)
        if n == 0:
            continue
        baseline = load_baseline(variant, station=False)  # simulated features: the shipped simulated baseline
        classifier = default_classifier(variant=variant)  # as the bench judges this variant's valves
        population_seed = seed * 1000 + 500 + v_index  # apart from the training and evaluation seeds
        valves = draw_population(variant, n, population_seed)
        features, converged = run_population(variant, valves, [population_seed * 100_000 + k for k in range(n)],
                                             workers)
        rel = features / np.array([baseline.af_v, baseline.a1_v_s_per_mm])
        verdicts, p, d = classifier.classify_many(np.nan_to_num(rel, nan=1.0))
        limit = variant.diagnosis.resistance_limit_n
        for k, valve in enumerate(valves):
            started = SHOP_START + dt.timedelta(hours=3 * index)
            valve_id = f"shop{seed}-{name}-{k:04d}"
            ok = bool(converged[k])
            store.add_row({
                "record_dir": f"simulated-shop:{seed}/{valve_id}", "started_at": started.isoformat(),
                "valve_id": valve_id, "pump_serial": f"sim-{seed}", "variant": name,
                "part_number": variant.pump.part_number, "verdict": str(verdicts[k]) if ok else Verdict.INVALID.value,
                "af_v": float(features[k, 0]), "a1_v_s_per_mm": float(features[k, 1]),
                "af_rel": float(rel[k, 0]) if ok else None, "a1_rel": float(rel[k, 1]) if ok else None,
                "probability_faulty": float(p[k]) if ok else None, "distance": float(d[k]) if ok else None,
                "station": "simulated shop", "operator": "simulation", "clock": "simulated",
                "software_version": "simulated-shop", "reason": "" if ok else "not converged",
                "model_name": classifier.name if ok else None, "model_sha256": classifier.sha256 if ok else None,
            })
            counts["tests"] += 1
            index += 1
            force = resisting_force_n(variant, valve)
            counts["worn_by_variant"] += int(force > limit)
            if not ok:
                counts["invalid"] += 1
                continue
            worn = force > scrap_factor * limit
            store.add_teardown(valve_id, "worn" if worn else "reusable", labelled_by="simulated shop",
                               labelled_at=(started + dt.timedelta(days=1)).isoformat(),
                               clearance_mm=round(valve.clearance_mm, 3),
                               note=f"resisting force {force:.2f} N, shop limit {scrap_factor * limit:.2f} N")
            counts["labelled"] += 1
            counts["worn_by_shop"] += int(worn)
    return counts


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m edc_bench.history.simulated_shop``: fill a history with a simulated shop's tests and teardowns."""
    parser = argparse.ArgumentParser(prog="python -m edc_bench.history.simulated_shop", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--db", required=True, metavar="URL", help="history database to fill (sqlite:///FILE)")
    parser.add_argument("--count", type=int, default=300, help="valves tested and torn down (default: 300)")
    parser.add_argument("--seed", type=int, default=11, help="seed of the shop's valves (default: 11)")
    parser.add_argument("--scrap-factor", type=float, default=DEFAULT_SCRAP_FACTOR,
                        help="the shop scraps above this share of the variant's limit "
                             f"(default: {DEFAULT_SCRAP_FACTOR})")
    args = parser.parse_args(argv)
    from edc_bench.errors import EdcBenchError

    try:
        with HistoryStore(args.db) as store:
            counts = simulate_shop(store, args.count, args.seed, scrap_factor=args.scrap_factor)
    except (EdcBenchError, ValueError) as exc:
        print(f"simulated_shop: error: {exc}", file=sys.stderr)
        return 2
    print(f"{counts['tests']} tests, {counts['labelled']} torn down and labelled ({counts['worn_by_shop']} worn by "
          f"the shop's limit, {counts['worn_by_variant']} by the variant's), {counts['invalid']} INVALID, in {shown_url(args.db)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
