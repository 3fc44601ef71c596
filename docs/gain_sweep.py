"""Print the table of docs/method.md, "Beyond the first order": ``python docs/gain_sweep.py``.

60 used valves of ``p-edc-hard`` (seed 5) on pumps whose solenoid's force constant varies by +/-10 % to +/-30 %
over the swing, either sign, each test stopped by the bench's rule (batch path): how many are judged, how well the
judged ones are identified, and whether their verdicts are right. About four minutes.
"""

from __future__ import annotations

from edc_bench.experiments.studies import gain_sweep
from edc_bench.verdict.classifier import default_classifier

VARIATIONS = (0.10, 0.15, 0.20, 0.22, 0.25, 0.30, -0.10, -0.15, -0.20, -0.22, -0.25, -0.30)


def main() -> None:
    print("| force constant over the swing | judged | INVALID, does not fit | af error, largest judged "
          "| a1 error, largest judged | faulty passed | reusable failed | gain variation identified | repeating part |")
    print("|---|---|---|---|---|---|---|---|---|")
    for row in gain_sweep(default_classifier(), list(VARIATIONS), 60, 5):
        low, high = row["gain_identified"]
        least, most = row["repeating_ratio"]
        af, a1 = (f"{row[key]:.1%}" if row["judged"] else "-" for key in ("af_error_max", "a1_error_max"))
        print(f"| {row['variation_rel']:+.0%} | {row['judged']} of {row['valves']} | {row['misfit']} "
              f"| {af} | {a1} | {row['faulty_passed']} "
              f"| {row['reusable_failed']} | {low:.0%}-{high:.0%} | {least:.1f}-{most:.1f} |", flush=True)


if __name__ == "__main__":
    main()
