"""``edc-bench evaluate``: the classifier on a held-out simulated population."""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import time
from typing import TYPE_CHECKING

from edc_bench.cli.common import (
    add_history_label_arguments,
    add_population_arguments,
    check_population_inputs,
    count_up_to,
)

if TYPE_CHECKING:
    from edc_bench.learning.evaluation import VerdictCounts

#: the populations of ``--coverage`` (:mod:`edc_bench.experiments.coverage`)
POPULATIONS = ("default", "hard", "stick-slip")


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Register the command."""
    p = sub.add_parser(
        "evaluate", help="judge a held-out simulated population and report accuracy",
        description="Simulate a fresh population (a seed not used in training) through the batch path, judge "
                    "every converged test with the classifier, and compare with the physical labels. "
                    "--from-history judges the shop's labelled tests instead, against their teardown findings.",
    )
    add_population_arguments(p, count=300, seed=777)
    add_history_label_arguments(p)
    p.add_argument("--time-to-verdict", action="store_true",
                   help="also stop each simulated test as the bench does (as soon as its verdict is certain) and "
                        "print the time to verdict (median, 95th percentile) and the early verdicts' accuracy "
                        "against the full-length tests'")
    p.add_argument("--coverage", action="store_true",
                   help="instead: how far the numbers behind the verdicts hold, on populations judged against a "
                        "baseline of a few simulated new valves (as a shop's is): af's and a1's error against the "
                        "truth, how often the early stop's 99 %% interval holds the true ratio, early stops certain "
                        "of a wrong verdict (docs/bench-test.md, 'Numbers to trust')")
    p.add_argument("--populations", nargs="+", choices=POPULATIONS, default=list(POPULATIONS), metavar="NAME",
                   help=f"with --coverage: which populations ({', '.join(POPULATIONS)}; default: all)")
    p.add_argument("--calibration-valves", type=count_up_to(50, " new valves for a baseline"), default=5,
                   metavar="N", help="with --coverage: new valves in each population's baseline (default: 5)")
    p.add_argument("--parts", action="store_true",
                   help="instead: which part is at fault, over simulated pumps whose rack binds or drags or whose "
                        "rack-travel sensor misreads, at several sizes around their limits, beside worn valves on a "
                        "sound pump: the confusion matrix part by part, each test the bench's whole path in "
                        "simulated time (docs/diagnosis.md, 'Which part is at fault'); --variants, --seed and "
                        "--tests-per-case apply")
    p.add_argument("--tests-per-case", type=count_up_to(500, " tests per case"), default=10, metavar="N",
                   help="with --parts: tests of each case, each on a valve of its own (default: 10; a test takes "
                        "about 0.6 s of one core)")
    p.add_argument("--json", action="store_true", help="print JSON")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    """Simulate, judge, report."""
    from edc_bench.learning.dataset import make_dataset
    from edc_bench.learning.evaluation import evaluate
    from edc_bench.verdict.classifier import ValveClassifier

    studies = [flag for flag, given in (("--coverage", args.coverage), ("--parts", args.parts),
                                        ("--from-history", args.from_history),
                                        ("--time-to-verdict", args.time_to_verdict)) if given]
    if len(studies) > 1:
        from edc_bench.errors import ConfigError

        count = "two" if len(studies) == 2 else str(len(studies))
        raise ConfigError(f"{' and '.join(studies)} are {count} different studies: give one of them")
    if args.parts:
        return _parts(args)
    # a given --model judges every variant; without it each variant's valves are judged by their own model (the
    # station's, or the one the variant names)
    classifier = ValveClassifier(args.model) if args.model is not None else None
    if args.from_history:
        classifier = classifier or ValveClassifier()  # the history's tests: the station's model
        from edc_bench.cli.common import history_label_dataset

        dataset, where = history_label_dataset(args.db, args.include_simulated)
        report = evaluate(classifier, dataset)
        if args.json:
            print(json.dumps({**dataclasses.asdict(report), "model": classifier.name}, indent=2))
            return 0
        print(f"{where}, judged by {classifier.name}", file=sys.stderr)
        _print_report(report, report.judged, "by teardown")
        return 0
    check_population_inputs(args)  # before minutes of simulation
    if args.coverage:
        return _coverage(args, classifier)
    if args.time_to_verdict:
        return _time_to_verdict(args, classifier)
    start = time.perf_counter()
    dataset = make_dataset(args.variants, args.count, args.seed)
    elapsed = time.perf_counter() - start
    report = evaluate(classifier, dataset)
    tests_per_minute = len(dataset) / elapsed * 60
    if args.json:
        print(json.dumps({**dataclasses.asdict(report), "tests_per_minute": tests_per_minute, "seed": args.seed},
                         indent=2))
        return 0
    print(f"held-out population: {report.tests} valves ({', '.join(args.variants)}), seed {args.seed}; "
          f"{tests_per_minute:.0f} bench tests per minute (batch path); judged by {', '.join(report.models)}",
          file=sys.stderr)
    print(f"INVALID (not converged): {report.invalid}")
    _print_report(report, report.judged, "by physics")
    return 0


def _parts(args: argparse.Namespace) -> int:
    """Which part is at fault over simulated faulty pumps, per variant: the confusion matrix and its headline."""
    import os

    from edc_bench.config import load_variant
    from edc_bench.studies.part_study import part_summary, part_table, run_part_study, study_json, summary_lines

    variants = [load_variant(name) for name in args.variants]  # every name checked before minutes of work
    out = {}
    for variant in variants:
        if not args.json:
            print(f"{variant.name}: {args.tests_per_case} tests a case ...", file=sys.stderr)
        results = run_part_study(variant, args.tests_per_case, args.seed, workers=min(2, os.cpu_count() or 1))
        summary = part_summary(results)
        if args.json:
            out[variant.name] = study_json(results)
            continue
        print(f"{variant.name}, seed {args.seed}:")
        print(part_table(results))
        for line in summary_lines(summary):
            print(f"  {line}")
    if args.json:
        print(json.dumps(out, indent=2))
    return 0


def _print_report(counts: VerdictCounts, judged: int, truth: str) -> None:
    print(f"MARGINAL: {counts.marginal} of {judged} ({counts.marginal_fraction:.1%})")
    print(f"accuracy outside the marginal band: {counts.accuracy_outside_band:.2%} "
          f"(faulty passed {counts.faulty_passed}, reusable failed {counts.reusable_failed}; "
          f"{counts.faulty} faulty, {counts.reusable} reusable {truth})")


def _time_to_verdict(args: argparse.Namespace, classifier) -> int:
    """Early stop against the full-length test on a simulated population, printed."""
    from edc_bench.experiments.studies import time_to_verdict

    report = time_to_verdict(classifier, list(args.variants), args.count, args.seed)
    if args.json:
        print(json.dumps({**dataclasses.asdict(report), "model": report.models}, indent=2))
        return 0
    print(f"time to verdict: {report.valves} simulated valves ({', '.join(args.variants)}), seed {args.seed}, "
          f"judged by {report.models}")
    print(f"  median {report.median_s:.1f} s, 95th percentile {report.p95_s:.1f} s")
    for name, v in report.per_variant.items():
        print(f"  {name}: median {v.median_s:.1f} s, 95th percentile {v.p95_s:.1f} s "
              f"(full length {v.full_length_s:g} s, {v.valves} valves)")
    for r, title in ((report.early, "stopped early"), (report.full, "full length")):
        print(f"{title}: INVALID {r.invalid}, MARGINAL {r.marginal} of {r.judged} "
              f"({r.marginal_fraction:.1%}), accuracy outside the marginal band {r.accuracy_outside_band:.2%} "
              f"(faulty passed {r.faulty_passed}, reusable failed {r.reusable_failed})")
    return 0


def _coverage(args: argparse.Namespace, classifier) -> int:
    """The numbers behind the verdicts against the simulation's truth, a population at a time, printed."""
    from edc_bench.experiments.coverage import TOLERANCE_REL, coverage_populations, coverage_study

    populations = coverage_populations()
    reports = []
    for name in args.populations:
        if not args.json:
            print(f"{name}: {args.count} valves against a baseline of {args.calibration_valves} new ones ...",
                  file=sys.stderr)
        reports.append(coverage_study(populations[name], classifier, args.count, args.seed, args.calibration_valves))
    model = ", ".join(sorted({r.model for r in reports}))
    if args.json:
        print(json.dumps({"model": model, "populations": [dataclasses.asdict(r) for r in reports]}, indent=2))
        return 0
    print(f"judged by {model}, seed {args.seed}; the truth is the simulated plant's; within: af "
          f"{TOLERANCE_REL['af']:.0%}, a1 {TOLERANCE_REL['a1']:.0%} of it; covered: the 99 % interval holds the "
          f"true ratio (the valve's true feature over the calibration valves' true mean)")
    for r in reports:
        print(f"{r.population} ({r.variant}, judged by {r.model}): {r.judged} of {r.valves} judged; baseline from "
              f"{r.baseline_tests} new valves, off its truth by af {r.af.baseline_error:+.1%}, "
              f"a1 {r.a1.baseline_error:+.1%}")
        for name, f in (("af", r.af), ("a1", r.a1)):
            print(f"  {name}: within {f.within:.1%}; |error| median {f.error_p50:.1%}, 95th percentile "
                  f"{f.error_p95:.1%}; bias {f.bias:+.1%}; interval covers the truth {f.covered:.1%} "
                  f"(median half width {f.half_width_p50:.1%})")
        print(f"  stopped certain {r.certain}, of which the truth contradicts {r.certain_wrong}; median stop "
              f"{r.median_stop_s:.1f} s; MARGINAL {r.marginal_fraction:.1%}; accuracy outside the marginal "
              f"band {r.accuracy_outside_band:.1%}")
    return 0
