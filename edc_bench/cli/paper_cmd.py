"""``edc-bench paper``: the paper's classification experiment, in simulation."""

from __future__ import annotations

import argparse
import dataclasses
import json
from pathlib import Path

from edc_bench.cli.common import check_output_file, count_up_to, given_path, seed_number


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
    p.add_argument("--figure", type=given_path, default=Path("paper-fig7.png"), metavar="PNG",
                   help="where to draw Fig. 7 (a .png file; default: paper-fig7.png)")
    p.add_argument("--json", action="store_true", help="print JSON")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    """Run the experiment, print the table, draw the figure."""
    from edc_bench.cli.common import require_extra

    require_extra("train", "the paper's experiment (it trains its classifier)")  # before minutes of simulation
    from edc_bench.config import load_variant
    from edc_bench.experiments.studies import PAPER_OUTCOME, draw_figure7, paper_experiment

    load_variant(args.variant)  # a bad variant or figure is refused before the experiment, not after it
    if args.runs == 1:
        check_output_file(args.figure, "--figure", ".png")
    if args.runs > 1:
        totals = []
        for seed in range(args.seed, args.seed + args.runs):
            run = paper_experiment(args.variant, seed).outcome
            totals.append(run.right)
            print(f"seed {seed}: {run.reusable_right}/{run.reusable} reusable, {run.faulty_right}/{run.faulty} faulty "
                  "right")
        print(f"{sum(t >= PAPER_OUTCOME.right for t in totals)} of {args.runs} runs at least as good as the paper "
              f"({PAPER_OUTCOME.right}/{PAPER_OUTCOME.valves})")
        return 0
    exp = paper_experiment(args.variant, args.seed)
    draw_figure7(exp, args.figure)
    paper, ours = PAPER_OUTCOME, exp.outcome
    if args.json:
        print(json.dumps({"paper": dataclasses.asdict(paper), "simulation": dataclasses.asdict(ours),
                          "figure": str(args.figure)}, indent=2))
        return 0
    print("                       paper (2010)   simulation")
    print(f"reusable judged normal  {paper.reusable_right:>2} / {paper.reusable:<2}        "
          f"{ours.reusable_right:>2} / {ours.reusable}")
    print(f"faulty judged abnormal  {paper.faulty_right:>2} / {paper.faulty:<2}        "
          f"{ours.faulty_right:>2} / {ours.faulty}")
    print(f"valves right            {paper.right} / {paper.valves}        {ours.right:>2} / {ours.valves}")
    print(f"figure: {args.figure}")
    return 0
