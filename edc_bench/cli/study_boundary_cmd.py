"""``edc-bench study-boundary``: where to put the decision boundary (paper, section 6)."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from edc_bench.cli.common import (
    add_history_label_arguments,
    add_population_arguments,
    check_output_file,
    check_population_inputs,
    given_path,
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
    p.add_argument("--figure", type=given_path, default=Path("boundary-tradeoff.png"), metavar="PNG",
                   help="where to draw the trade-off (a .png file; default: boundary-tradeoff.png)")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    """Simulate, sweep, plot, print."""
    from edc_bench.experiments.studies import boundary_tradeoff, draw_tradeoff
    from edc_bench.learning.dataset import make_dataset

    check_output_file(args.figure, "--figure", ".png")  # before the work, not after it
    if not args.from_history:
        check_population_inputs(args)
    judge = _judge(args)  # before the work too
    if args.from_history:
        from edc_bench.cli.common import history_label_dataset

        dataset, title = history_label_dataset(args.db, args.include_simulated)
        if len(set(dataset.labels.tolist())) < 2:
            from edc_bench.errors import ConfigError

            raise ConfigError(f"{title}, all {'worn or faulty' if dataset.labels[0] else 'reusable'}: the trade-off "
                              "needs teardowns of both reusable and worn valves")
    else:
        dataset = make_dataset(args.variants, args.count, args.seed)
        title = f"{len(dataset)} simulated valves ({', '.join(args.variants)})"
    curve = boundary_tradeoff(judge, dataset)
    draw_tradeoff(curve, args.figure, title)
    print("boundary shift   needless replacements   faulty passed")
    for k in range(0, len(curve.shift), 5):
        print(f"{curve.shift[k]:+14.2f}   {curve.needless_replacement[k]:21.1%}   {curve.faulty_passed[k]:13.1%}")
    print(f"figure: {args.figure}")
    return 0


def _judge(args: argparse.Namespace) -> Any:
    """``--model``, else the model the variants' valves are judged by (the history's tests: the station's); one
    boundary is shifted, so variants judged by different models are refused."""
    from edc_bench.config import load_variant
    from edc_bench.errors import ConfigError
    from edc_bench.verdict.classifier import ValveClassifier, variant_model_path

    if args.model is not None or args.from_history:
        return ValveClassifier(args.model)
    paths = {variant_model_path(load_variant(name)) for name in args.variants}
    if len(paths) > 1:
        raise ConfigError(f"--variants {' '.join(args.variants)} are judged by different models "
                          f"({', '.join(sorted(p.name for p in paths))}): study one model's boundary at a time, "
                          "with the variants it judges, or give --model")
    return ValveClassifier(paths.pop())
