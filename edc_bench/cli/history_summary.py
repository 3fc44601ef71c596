"""``edc-bench history --summary``: the chain's figures for the listing's filters (the web view's chain page shows
the same, from the same query: :mod:`edc_bench.history.summary`)."""

from __future__ import annotations

import argparse
import json
from dataclasses import asdict
from typing import TYPE_CHECKING

from edc_bench.cli.common import print_quietly_if_closed
from edc_bench.timefmt import local_text

if TYPE_CHECKING:  # the parser is built before any test's first tick: SQLAlchemy only when a summary is asked for
    from edc_bench.history.summary import ChainSummary


def _rate(value: float | None) -> str:
    return "-" if value is None else f"{value * 100:.1f} %"


def summary_lines(summary: ChainSummary) -> list[str]:
    """The figures as a person reads them at a terminal."""
    lines = [f"{summary.tests} test(s): " + (", ".join(f"{v} {n}" for v, n in summary.verdicts) or "none"),
             f"first tests: {summary.first_tests}; first-pass rate {_rate(summary.first_pass_rate)} "
             f"({summary.first_pass} PASS); MARGINAL rate {_rate(summary.marginal_rate)} "
             f"({summary.first_marginal} MARGINAL, {summary.retests} retest(s) done)"]
    if summary.invalid_areas:
        lines.append("INVALID by where to look: " + ", ".join(f"{a} {n}" for a, n in summary.invalid_areas))
    for shop, stations, tests in summary.shops:
        lines.append(f"shop {shop}: {stations} station(s), {tests} test(s)")
    for s in summary.stations:
        lines.append(f"station {s.station}" + (f" (shop {s.shop})" if s.shop else "")
                     + f": {s.tests} test(s), latest test {local_text(s.last_test_at, empty='never')}"
                     f", latest self-check {local_text(s.last_check_at, empty='never')}"
                     + (" - QUIET" if s.quiet else ""))
    return lines


def print_summary(summary: ChainSummary, as_json: bool) -> None:
    """Print the figures (``--json``: every figure, rates included, as one object)."""
    if as_json:
        data = {**asdict(summary), "first_pass_rate": summary.first_pass_rate,
                "marginal_rate": summary.marginal_rate,
                "shops": [{"shop": shop, "stations": n, "tests": t} for shop, n, t in summary.shops]}
        print_quietly_if_closed(lambda: print(json.dumps(data, indent=2)))
        return
    print_quietly_if_closed(lambda: print("\n".join(summary_lines(summary))))


def add_summary_arguments(p: argparse.ArgumentParser) -> None:
    """``--summary`` and the filter only it and the listing take (``--operator``)."""
    p.add_argument("--summary", action="store_true",
                   help="the chain's figures for the filters given (--since, --until, --variant, --station, "
                        "--operator; a rig's tests only, unless --include-simulated): the verdict mix, the first-pass and MARGINAL rates, INVALID tests by where "
                        "to look, each station's latest test and self-check (QUIET: no test for 7 days)")
    p.add_argument("--operator", default=None, metavar="NAME", help="only this technician's tests")
