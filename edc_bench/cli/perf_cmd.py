"""``edc-bench perf``: the timing and speed benchmark (a benchmark, not a test)."""

from __future__ import annotations

import argparse
import dataclasses
import datetime
import json
import os
import platform
import sys
from typing import Any

from edc_bench.cli.common import print_quietly_if_closed


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Register the command."""
    from edc_bench.perf import GROUPS

    p = sub.add_parser(
        "perf",
        help="measure timing and speed against their floors and targets",
        description="Measure, in one run, the controller tick, the codec, the simulated bench test, the real-time "
                    "loop at 1 and 2 kHz against the rig process (beside a bare loop: this machine's floor), the "
                    "batch path's throughput and the start-up times, each beside the reference it should approach "
                    "and its target. The full run takes about 6 minutes (the real-time loops run 60 s each); "
                    "--quick takes well under a minute. Figures, not pass/fail: the exit code is 0 when it ran.",
    )
    p.add_argument("--quick", action="store_true", help="short runs of every group (a smoke run, noisy figures)")
    p.add_argument("--json", action="store_true", help="print only JSON on stdout")
    p.add_argument("--only", action="append", choices=GROUPS, metavar="GROUP",
                   help=f"run only this group (repeatable): {', '.join(GROUPS)}")
    p.add_argument("--variant", default=None, help="pump variant (name, part number or file; default: the default)")
    p.set_defaults(run=run)


@dataclasses.dataclass(frozen=True)
class PerfEnvironment:
    """Where, when and how ``perf`` measured (its JSON's ``environment``).

    Attributes
    ----------
    date : str
        When the run started (UTC, ISO 8601).
    edc_bench, python, machine : str
        The versions and the machine's architecture.
    cpus : int or None
        The CPUs the machine has.
    quick : bool
        A quick (smoke) run.
    command : str
        The command as given.
    cpu_steal_s : float
        CPU time the hypervisor took during the run (s).
    """

    date: str
    edc_bench: str
    python: str
    machine: str
    cpus: int | None
    quick: bool
    command: str
    cpu_steal_s: float = 0.0

    @classmethod
    def now(cls, quick: bool, command: str) -> PerfEnvironment:
        """This machine, now (the steal is set at the run's end)."""
        from edc_bench import __version__

        return cls(date=datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"), edc_bench=__version__,
                   python=platform.python_version(), machine=platform.machine(), cpus=os.cpu_count(), quick=quick,
                   command=command)


def _table(figures: list[Any], env: PerfEnvironment) -> None:
    from rich.console import Console
    from rich.table import Table

    table = Table(title=f"edc-bench perf, {env.date} ({env.cpus} CPUs, Python {env.python}"
                        f"{', quick' if env.quick else ''})", show_lines=False)
    for col in ("group", "figure", "measured", "reference", "target", "met", "notes"):
        table.add_column(col, overflow="fold")
    for f in figures:
        ref = "" if f.reference is None else f"{f.reference:.3g} {f.unit} ({f.reference_name})"
        met = {True: "yes", False: "NO", None: ""}[f.met]
        table.add_row(f.group, f.name, f"{f.value:.3g} {f.unit}", ref, f.target, met, f.note)
    Console(width=None if sys.stdout.isatty() else 200).print(table)
    print(f"CPU steal during the run: {env.cpu_steal_s:.2f} s (this machine is a shared VM; see the notes)")


def unjudged(figures: list[Any]) -> list[Any]:
    """A quick run's figures with no target judged: its runs are too short for the targets (a smoke run), so a
    'NO' there would say nothing of the station."""
    import dataclasses

    return [f if f.met is None else dataclasses.replace(
        f, met=None, note="; ".join(filter(None, (f.note, "target not judged: a quick run is too short for it"))))
        for f in figures]


def run(args: argparse.Namespace) -> int:
    """Run the chosen groups and report."""
    from edc_bench.perf import suite
    from edc_bench.runtime.clock import cpu_steal_s

    groups = tuple(dict.fromkeys(args.only)) if args.only else suite.GROUPS
    if args.variant is not None:
        from edc_bench.config import load_variant

        load_variant(args.variant)  # a bad name is refused before anything runs
    steal_at_start_s = cpu_steal_s()
    command = ("edc-bench perf" + (" --quick" if args.quick else "")
               + "".join(f" --only {g}" for g in (args.only or ())) + (" --json" if args.json else ""))
    env = PerfEnvironment.now(args.quick, command)

    def announce(figure: Any) -> None:
        if not args.json:
            print(f"  {figure.group}: {figure.name}: {figure.value:.3g} {figure.unit}", file=sys.stderr, flush=True)

    if not args.json:
        print(f"edc-bench perf: {', '.join(groups)}{' (quick)' if args.quick else ''}", file=sys.stderr, flush=True)
    from edc_bench.session.latency import session_latency

    figures = suite.run(groups, quick=args.quick, variant_name=args.variant, on_figure=announce,
                        session_latency=session_latency)
    if args.quick:
        figures = unjudged(figures)
    env = dataclasses.replace(env, cpu_steal_s=cpu_steal_s() - steal_at_start_s)
    if args.json:
        from edc_bench.records.writer import json_safe

        print_quietly_if_closed(lambda: print(json.dumps(json_safe(
            {"environment": dataclasses.asdict(env), "figures": [f.as_dict() for f in figures]}), indent=2)))
    else:
        print_quietly_if_closed(lambda: _table(figures, env))
    return 0
