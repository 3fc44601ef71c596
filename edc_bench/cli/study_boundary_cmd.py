"""``edc-bench study-boundary``: where to put the decision boundary (paper, section 6)."""

from __future__ import annotations

import argparse
from pathlib import Path

from edc_bench.cli.common import (
    add_history_label_arguments,
    add_population_arguments,
    check_output_file,
    check_population_inputs,
)


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Register the command."""
    p = sub.add_parser(
        "study-boundary", help="trade-off of needless replacements against faulty valves passed",
        description="Simulate a large population, move the classifier's boundary in steps, and plot the share of "
                    "reusable valves replaced needlessly against the share of faulty valves passed. "
                    "--from-history does it on the shop's labelled tests (teardown findings) instead.",
    )
    add_population_arguments(p, count=1000, seed=31)
    add_history_label_arguments(p)
    p.add_argument("--figure", type=Path, default=Path("boundary-tradeoff.png"), metavar="PNG",
                   help="where to draw the trade-off (a .png file; default: boundary-tradeoff.png)")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    """Simulate, sweep, plot, print."""
    from edc_bench.experiments.studies import boundary_tradeoff, draw_tradeoff
    from edc_bench.learning.dataset import make_dataset
    from edc_bench.verdict.classifier import ValveClassifier

    check_output_file(args.figure, "--figure", ".png")  # before the work, not after it
    if args.from_history:
        from edc_bench.cli.common import history_label_dataset

        dataset, title = history_label_dataset(args.db, args.include_simulated)
        if len(set(dataset.labels.tolist())) < 2:
            from edc_bench.errors import ConfigError

            raise ConfigError(f"{title}, all {'worn or faulty' if dataset.labels[0] else 'reusable'}: the trade-off "
                              "needs teardowns of both reusable and worn valves")
    else:
        check_population_inputs(args)
        dataset = make_dataset(args.variants, args.count, args.seed)
        title = f"{len(dataset)} simulated valves ({', '.join(args.variants)})"
    curve = boundary_tradeoff(ValveClassifier(args.model), dataset)
    draw_tradeoff(curve, args.figure, title)
    print("boundary shift   needless replacements   faulty passed")
    for k in range(0, len(curve["shift"]), 5):
        print(f"{curve['shift'][k]:+14.2f}   {curve['needless_replacement'][k]:21.1%}   {curve['faulty_passed'][k]:13.1%}")
    print(f"figure: {args.figure}")
    return 0
