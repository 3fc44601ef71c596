"""``edc-bench evaluate``: the classifier on a held-out simulated population."""

from __future__ import annotations

import argparse
import json
import sys
import time

from edc_bench.cli.common import add_population_arguments


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Register the command."""
    p = sub.add_parser(
        "evaluate", help="judge a held-out simulated population and report accuracy",
        description="Simulate a fresh population (a seed not used in training) through the batch path, judge "
                    "every converged test with the classifier, and compare with the physical labels.",
    )
    add_population_arguments(p, count=300, seed=777)
    p.add_argument("--json", action="store_true", help="print JSON")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    """Simulate, judge, report."""
    from edc_bench.diagnosis.classifier import ValveClassifier
    from edc_bench.diagnosis.dataset import make_dataset
    from edc_bench.diagnosis.experiments import evaluate

    start = time.perf_counter()
    dataset = make_dataset(args.variants, args.count, args.seed)
    elapsed = time.perf_counter() - start
    report = evaluate(ValveClassifier(args.model), dataset)
    report["tests_per_minute"] = len(dataset) / elapsed * 60
    report["seed"] = args.seed
    if args.json:
        print(json.dumps(report, indent=2))
        return 0
    print(f"held-out population: {report['tests']} valves ({', '.join(args.variants)}), seed {args.seed}; "
          f"{report['tests_per_minute']:.0f} bench tests per minute (batch path)", file=sys.stderr)
    print(f"INVALID (not converged): {report['invalid']}")
    print(f"MARGINAL: {report['marginal']} of {report['judged']} ({report['marginal_fraction']:.1%})")
    print(f"accuracy outside the marginal band: {report['accuracy_outside_band']:.2%} "
          f"(faulty passed {report['faulty_passed']}, reusable failed {report['reusable_failed']}; "
          f"{report['faulty']} faulty, {report['reusable']} reusable by physics)")
    return 0
