"""``edc-bench check-station``: does this PC hold the bench loop's rate?"""

from __future__ import annotations

import argparse
import dataclasses
import json
from typing import Any

from edc_bench.cli.common import print_quietly_if_closed
from edc_bench.cli.exit_codes import ExitCode


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Register the command."""
    p = sub.add_parser(
        "check-station", help="measure whether this PC holds the loop rate (GO / NO-GO)",
        description="Run the bench loop's clock for about 10 s with nothing else in the tick (like cyclictest), "
                    "report lateness percentiles and overruns, and say GO or NO-GO with advice. Exit 0 for GO, "
                    "14 for NO-GO.",
    )
    p.add_argument("--variant", default=None, help="variant whose tick period and overrun limit apply")
    p.add_argument("--duration-s", type=float, default=10.0, metavar="S", help="how long to measure (default 10)")
    p.add_argument("--json", action="store_true", help="print only JSON")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    """Measure, judge, advise."""
    from edc_bench.config import load_variant
    from edc_bench.errors import ConfigError
    from edc_bench.station import check_station

    if not 0.5 <= args.duration_s <= 600:
        raise ConfigError(f"--duration-s must be between 0.5 and 600 s, got {args.duration_s:g}")
    variant = load_variant(args.variant)
    period_s = variant.controller.period_s
    if not args.json:
        print(f"measuring the loop at {1 / period_s:g} Hz for {args.duration_s:g} s ...", flush=True)
    result = check_station(period_s, args.duration_s, variant.acceptance.max_overrun_fraction)
    print_quietly_if_closed(lambda: _report(result, args.json))
    return ExitCode.OK if result.verdict == "GO" else ExitCode.STATION_NOT_READY


def _report(result: Any, as_json: bool) -> None:
    if as_json:
        from edc_bench.records.writer import json_safe

        print(json.dumps(json_safe(dataclasses.asdict(result)), indent=2))
        return
    from rich.console import Console
    from rich.panel import Panel
    from rich.table import Table
    from rich.text import Text

    body = Table.grid(padding=(0, 2))
    body.add_column(style="bold", justify="right")
    body.add_column()
    style = "bold white on green" if result.verdict == "GO" else "bold white on red"
    body.add_row("verdict", Text.assemble((f" {result.verdict} ", style)))
    late = result.lateness_us
    body.add_row("lateness", f"p50 {late['p50']:.0f} us, p99 {late['p99']:.0f} us, p99.9 {late['p99.9']:.0f} us, "
                             f"max {late['max']:.0f} us (tick {result.period_s * 1e6:.0f} us)")
    body.add_row("overruns", f"{result.overruns} of {result.ticks} ticks (a test allows {result.overrun_limit:.1%})")
    body.add_row("CPU steal", f"{result.steal_s:.2f} s")
    body.add_row("priority", str(result.system.get("measured_at", "")))
    for n, reason in enumerate(result.reasons):
        body.add_row("why" if n == 0 else "", reason)
    for n, line in enumerate(result.advice):
        body.add_row("advice" if n == 0 else "", line)
    Console().print(Panel(body, title="edc-bench check-station", border_style="green" if result.verdict == "GO"
                          else "red"))
