"""``edc-bench rig-check``: does a rig keep ICD v1? GO / NO-GO, with every check's figure."""

from __future__ import annotations

import argparse
import json
from datetime import datetime
from pathlib import Path
from typing import TYPE_CHECKING, Any

from edc_bench.cli.common import given_path

from edc_bench.cli.exit_codes import ExitCode

if TYPE_CHECKING:
    from edc_bench.runtime.bus_config import BusSettings


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Register the command."""
    from edc_bench.cli.common import add_bus_arguments, add_variant_arguments

    p = sub.add_parser(
        "rig-check", help="check a rig against ICD v1 (GO / NO-GO), before its first valve",
        description="Talk to a rig as the bench does and check, one measured figure each, that it keeps ICD v1: "
                    "heartbeat period, a valid command answered once with its counter, invalid frames ignored, "
                    "every command answered, reply latency, the watchdog and its latch, SAFE applying 0 V, samples "
                    "taken before the new drive. The rack is never driven beyond a hold below the spring's "
                    "preload, and the rig is left in SAFE. Without --interface/--channel it checks the simulated "
                    "rig in simulated time (with --break, one that breaks a rule). Writes rig-check.json and a "
                    "one-page rig-check.pdf. Exit 0 for GO, 15 for NO-GO.",
    )
    add_bus_arguments(p)
    add_variant_arguments(p)
    p.add_argument("--commands", type=_commands, default=2000, metavar="N",
                   help="commands in the reply-latency run, at 1 kHz (default 2000)")
    p.add_argument("--break", dest="breaks", action="append", default=[], metavar="RULE",
                   help="the simulated rig only: break this ICD rule, to see the check catch it (repeatable): "
                        + ", ".join(_break_names()))
    p.add_argument("--firmware", choices=("python", "c"), default="python",
                   help="the simulated rig only: its firmware, python (the prototype, default) or c (the C core)")
    p.add_argument("--provoke-trips", action="store_true",
                   help="also provoke the over-current and travel-limit trips: drives the rack to its stop and the "
                        "coil beyond its rating for a millisecond; only on a rig built for it")
    p.add_argument("--out", type=given_path, default=None, metavar="DIR",
                   help="where rig-check.json and rig-check.pdf go (default: rig-checks/<date-time>)")
    p.add_argument("--json", action="store_true", help="print only JSON")
    p.set_defaults(run=run)


def _break_names() -> list[str]:
    from edc_bench.sim.broken_rigs import IcdBreak

    return [rule.value for rule in IcdBreak]


def _commands(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        value = 0
    if not 100 <= value <= 100_000:
        raise argparse.ArgumentTypeError(f"{text}: give a whole number of commands from 100 to 100000, e.g. 2000")
    return value


def run(args: argparse.Namespace) -> int:
    """Check the rig, print the table (or JSON), write the files; GO or NO-GO."""
    from edc_bench.cli.common import bus_settings, print_quietly_if_closed
    from edc_bench.config import load_variant
    from edc_bench.errors import ConfigError
    from edc_bench.rigcheck.report import as_json, print_table, write_files

    bus_config = bus_settings(args.interface, args.channel, args.bitrate, configured_alone=False,
                              options=args.bus_options)
    if bus_config is not None and (args.breaks or args.firmware != "python"):
        raise ConfigError("--break and --firmware apply to the simulated rig only: leave out --interface/--channel, "
                          "or them")
    breaks = _parse_breaks(args.breaks)
    variant = load_variant(args.variant)
    folder = args.out or Path("rig-checks") / datetime.now().strftime("%Y%m%d-%H%M%S")
    _check_folder(folder)
    report = _check(bus_config, variant, args, breaks, datetime.now().astimezone().strftime("%Y-%m-%d %H:%M %Z"))
    json_path, pdf_path = write_files(report, folder)
    if args.json:
        print_quietly_if_closed(lambda: print(json.dumps(as_json(report), indent=2)))
    else:
        print_quietly_if_closed(lambda: (print_table(report), print(f"wrote {json_path} and {pdf_path}")))
    return ExitCode.OK if report.go else ExitCode.RIG_NOT_CONFORMING


def _parse_breaks(names: list[str]) -> frozenset[Any]:
    from edc_bench.errors import ConfigError
    from edc_bench.sim.broken_rigs import IcdBreak

    try:
        return frozenset(IcdBreak.parse(name) for name in names)
    except ValueError as exc:
        raise ConfigError(f"--break: {exc}") from None


def _check_folder(folder: Path) -> None:
    """Refuse an --out that is a file or cannot be made, before talking to the rig."""
    from edc_bench.errors import ConfigError

    if folder.exists() and not folder.is_dir():
        raise ConfigError(f"--out {folder}: a file is there; give a folder")
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ConfigError(f"--out {folder}: cannot make the folder ({exc.strerror}); give another") from None


def _check(bus_config: BusSettings | None, variant: Any, args: argparse.Namespace, breaks: frozenset[Any],
           when: str) -> Any:
    """Run the checks on the configured bus in real time, or on the in-process simulated rig in simulated time."""
    from edc_bench.protocol import default_icd
    from edc_bench.rigcheck import run_rig_check
    from edc_bench.runtime.bus import ClosingBus, open_bus

    if bus_config is not None:
        from edc_bench.runtime.clock import RealTimeClock

        where = ", ".join(f"{k}={v}" for k, v in bus_config.items())
        with ClosingBus(open_bus(bus_config, default_icd().bitrate)) as bus:
            return run_rig_check(bus, RealTimeClock(), variant, where=where, commands=args.commands, when=when,
                                 provoke_trips=args.provoke_trips)
    from edc_bench.physics.valve import parse_valve_spec
    from edc_bench.runtime.clock import SimulatedClock
    from edc_bench.sim.inprocess import InProcessRig
    from edc_bench.sim.lockstep_bus import lockstep_pair
    from edc_bench.sim.rig import RigOptions, SimulatedRig

    rig = SimulatedRig(variant, parse_valve_spec(args.valve, variant),
                       options=RigOptions(breaks=breaks, firmware=args.firmware))
    bench_end, rig_end = lockstep_pair()
    with ClosingBus(bench_end) as bus, ClosingBus(rig_end):
        where = f"simulated rig ({args.firmware} firmware), simulated time" + (f", breaking {', '.join(sorted(b.value for b in breaks))}"
                                                   if breaks else "")
        return run_rig_check(bus, SimulatedClock(InProcessRig(rig_end, rig)), variant, where=where,
                             commands=args.commands, when=when, provoke_trips=args.provoke_trips)
