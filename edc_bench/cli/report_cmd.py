"""``edc-bench report``: the one-page printable report of a test."""

from __future__ import annotations

import argparse
from pathlib import Path


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Register the command."""
    p = sub.add_parser(
        "report", help="one-page report of a test (PDF and PNG)",
        description="Draw the customer report of a record folder: identity and versions, the verdict with its "
                    "probability and distance to the boundary, the parameter table against the baseline, the "
                    "tracking and convergence plots and the valve on the decision plane. Writes report.pdf and "
                    "report-page.png into the record folder (or --out).",
    )
    p.add_argument("record_dir", type=Path, help="a record folder written by 'edc-bench test'")
    p.add_argument("--out", type=Path, default=None, metavar="DIR", help="folder for the report (default: the record's)")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    """Draw and say where."""
    from edc_bench.records.report import draw_report

    pdf, png = draw_report(args.record_dir, args.out)
    print(f"report: {pdf}\npage image: {png}")
    return 0
