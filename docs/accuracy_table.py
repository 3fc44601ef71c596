"""Print the tables of docs/bench-test.md, "Measured accuracy": ``python docs/accuracy_table.py``.

Each shipped test variant, new, worn and faulty valve, seed 1, stopped early as the bench does: on the plant the
identification assumes ("model": Coulomb friction only, no sensor noise) and on the default simulated plant,
without latency; then the default plant through the simulated USB full-speed adapter (``--adapter usb-fs``).
About a minute.
"""

from __future__ import annotations

from edc_bench.bench import run_simulated_test
from edc_bench.config import load_variant

VARIANTS = ("p-edc-default", "p-edc-long", "p-edc-hard")
VALVES = ("new", "worn", "faulty")
PLANTS = (("model", {"stiction": False, "sensor_noise": False}), ("default", {}), ("default, usb-fs",
                                                                                    {"adapter": "usb-fs"}))


def row(variant_name: str, valve: str, plant: str, options: dict) -> str:
    result = run_simulated_test(load_variant(variant_name), valve, 1, **options)
    ident = result.judgement.identification
    fit = ident.model_fit
    errors = " | ".join(f"{result.parameters[n]['error_rel']:+.1%}" for n in ("a2", "a1", "a0", "b", "af"))
    return (f"| {variant_name} | {valve} | {plant} | {errors} | {result.verdict.value} at "
            f"{result.stop['time_s']:.1f} s | {fit.residual_ratio:.1f} | {fit.systematic_ratio:.1f} | "
            f"{max(fit.spread_rel.values()):.1%} | {fit.gain_variation_rel:.0%} | {ident.condition_number:.0f} |")


def main() -> None:
    print("| variant | valve | plant | a2 | a1 | a0 | b | af | verdict, stop | residual | repeating | spread | gain "
          "| cond. |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for variant_name in VARIANTS:
        for valve in VALVES:
            for plant, options in PLANTS:
                print(row(variant_name, valve, plant, options), flush=True)


if __name__ == "__main__":
    main()
