"""``edc-bench paper``: the paper's classification experiment, in simulation."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from edc_bench.cli.common import check_output_file, count_up_to, seed_number


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Register the command."""
    p = sub.add_parser(
        "paper", help="reproduce the paper's experiment (needs the 'train' extra)",
        description="Train the paper's network on 6 simulated valves (4 new, 2 severely worn) x 3 tests, judge 18 "
                    "used valves (10 reusable, 8 faulty by physics) x 3 tests, print the outcome next to the "
                    "paper's, and draw the paper's Fig. 7.",
    )
    p.add_argument("--variant", default="p-edc-default", metavar="NAME|PART|PATH",
                   help="variant to simulate (default: p-edc-default)")
    p.add_argument("--seed", type=seed_number, default=2010, help="seed (default: 2010)")
    p.add_argument("--runs", type=count_up_to(100, " (each run is minutes)"), default=1,
                   help="repeat with seeds seed, seed+1, ... and report each (default: 1)")
    p.add_argument("--figure", type=Path, default=Path("paper-fig7.png"), metavar="PNG",
                   help="where to draw Fig. 7 (a .png file; default: paper-fig7.png)")
    p.add_argument("--json", action="store_true", help="print JSON")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    """Run the experiment, print the table, draw the figure."""
    from edc_bench.config import load_variant
    from edc_bench.experiments.studies import PAPER_OUTCOME, draw_figure7, paper_experiment

    load_variant(args.variant)  # a bad variant or figure is refused before the experiment, not after it
    if args.runs == 1:
        check_output_file(args.figure, "--figure", ".png")
    if args.runs > 1:
        totals = []
        for seed in range(args.seed, args.seed + args.runs):
            run_exp = paper_experiment(args.variant, seed)
            totals.append(run_exp.reusable_right + run_exp.faulty_right)
            print(f"seed {seed}: {run_exp.reusable_right}/10 reusable, {run_exp.faulty_right}/8 faulty right")
        print(f"{sum(t >= 17 for t in totals)} of {args.runs} runs at least as good as the paper (17/18)")
        return 0
    exp = paper_experiment(args.variant, args.seed)
    draw_figure7(exp, args.figure)
    ours = {"reusable_right": exp.reusable_right, "reusable": int((~exp.test_truth).sum()),
            "faulty_right": exp.faulty_right, "faulty": int(exp.test_truth.sum())}
    if args.json:
        print(json.dumps({"paper": PAPER_OUTCOME, "simulation": ours, "figure": str(args.figure)}, indent=2))
        return 0
    print("                       paper (2010)   simulation")
    print(f"reusable judged normal  {PAPER_OUTCOME['reusable_right']:>2} / {PAPER_OUTCOME['reusable']:<2}        "
          f"{ours['reusable_right']:>2} / {ours['reusable']}")
    print(f"faulty judged abnormal  {PAPER_OUTCOME['faulty_right']:>2} / {PAPER_OUTCOME['faulty']:<2}        "
          f"{ours['faulty_right']:>2} / {ours['faulty']}")
    total = ours["reusable_right"] + ours["faulty_right"]
    print(f"valves right            17 / 18        {total:>2} / 18")
    print(f"figure: {args.figure}")
    return 0
