"""``edc-bench replay``: the identification and the verdict again, from a test's CAN log."""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import TYPE_CHECKING, Any

from edc_bench.cli.common import given_path, print_quietly_if_closed
from edc_bench.cli.exit_codes import ExitCode, exit_code_for

if TYPE_CHECKING:
    from edc_bench.replay import ReplayReport


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Register the command."""
    p = sub.add_parser(
        "replay", help="re-run identification and classification from a test's CAN log",
        description="Feed the rack positions logged in a record folder's can.log to a fresh controller, tick by "
                    "tick, and judge the rebuilt trace as the test did. With a record folder the result is "
                    "compared with the recorded one (exit 0 if reproduced exactly, 13 if not); --can-log FILE replays "
                    "another log of the same test instead (the can.log converted by 'python -m can.logconvert', the "
                    "record's trace.mf4). With --can-log and --variant and no folder, a raw log is replayed on its "
                    "own (exit code of the verdict). Logs: candump .log, .asc, .blf, .mf4, .trc (also gzipped).",
    )
    p.add_argument("record_dir", nargs="?", type=given_path, default=None, help="a record folder")
    p.add_argument("--can-log", type=given_path, default=None, metavar="FILE",
                   help="a CAN log in any format python-can reads (.log .asc .blf .mf4 .trc .csv .db, also "
                        ".gz; the suffix names it)")
    p.add_argument("--variant", default=None, help="with --can-log: the variant the test ran (name, part number, file)")
    p.add_argument("--model", type=given_path, default=None, metavar="ONNX",
                   help="classifier model (default: the one that judged the record, found by its hash; else the "
                        "station's)")
    p.add_argument("--nominal-baseline", action="store_true",
                   help="with --can-log: judge a variant that has no measured baseline against the nominal one "
                        "(a record replays the way it was judged)")
    p.add_argument("--json", action="store_true", help="print only JSON")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    """Replay and report."""
    from edc_bench.errors import ConfigError
    from edc_bench.replay import replay_can_log, replay_record

    if args.record_dir is None and args.can_log is None:
        raise ConfigError("give a record folder (optionally with --can-log FILE), or --can-log FILE with --variant")
    if args.record_dir is not None:
        if args.variant is not None:
            raise ConfigError("a record folder carries its variant; --variant goes with --can-log and no folder")
        report = replay_record(args.record_dir, args.model, args.can_log)
    else:
        from edc_bench.config import load_variant

        if args.variant is None:
            raise ConfigError("--can-log needs --variant: the variant the test ran with")
        report = replay_can_log(args.can_log, load_variant(args.variant), args.model, args.nominal_baseline)
    print_quietly_if_closed(lambda: _print(report, args.json))
    if report.compared:
        return ExitCode.OK if report.reproduced else ExitCode.NOT_REPRODUCED
    return exit_code_for(report.judged.verdict)


def _summary(report: ReplayReport) -> dict[str, Any]:
    from edc_bench.records.writer import json_safe

    j = report.judged
    return json_safe({
        "verdict": j.verdict, "reasons": j.reasons, "features": j.features,
        "parameters": {n: {"value": p.value, "std": p.std} for n, p in j.parameters.items()},
        "classification": j.classification, "ticks": report.run.ticks,
        "missed_replies": report.run.missed_replies,
        "max_drive_deviation_v": report.run.max_drive_deviation_v,
        "compared_with_record": report.compared, "reproduced": report.reproduced if report.compared else None,
        "differences": report.differences, "notes": report.notes,
    })


def _print(report: ReplayReport, as_json: bool) -> None:
    if as_json:
        print(json.dumps(_summary(report), indent=2))
        return
    run, judged = report.run, report.judged
    print(f"replayed {run.ticks} ticks ({run.missed_replies} replies missing); drives match the logged "
          f"commands to {run.max_drive_deviation_v * 1e3:.2f} mV")
    print(f"verdict: {judged.verdict}")
    for reason in judged.reasons:
        print(f"  - {reason}")
    print(f"features: af = {judged.features.af:.6g} V, a1 = {judged.features.a1:.6g} V s/mm")
    if report.compared:
        if report.reproduced:
            exactly = "" if report.notes else "exactly "
            print(f"reproduced: verdict, parameters and their uncertainties, P(faulty) and distance are {exactly}"
                  "the recorded ones")
        else:
            print("NOT reproduced:")
            for line in report.differences:
                print(f"  - {line}")
        for line in report.notes:
            print(f"note: {line}")
    else:
        for line in report.differences:
            print(f"  - {line}")
