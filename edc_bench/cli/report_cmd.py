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
    from edc_bench.cli.common import check_output_folder, probe_writable
    from edc_bench.records.reader import load_record
    from edc_bench.records.report import draw_report

    _check_text(load_record(args.record_dir), args.record_dir)  # a folder that is not a record, and ...
    if args.out is not None:
        check_output_folder(args.out, "--out")  # ... an --out that cannot take the report, refused before drawing
    else:
        probe_writable(args.record_dir, f"{args.record_dir}: the record folder is not writable; write the report "
                                        "elsewhere with --out DIR")
    pdf, png = draw_report(args.record_dir, args.out)
    print(f"report: {pdf}\npage image: {png}")
    return 0


def _check_text(record: object, folder: Path, key: str = "record") -> None:
    """Refuse a record holding text that is not valid Unicode (hand-edited, or bytes an older edc-bench kept).

    The report draws the record's text; such text cannot be drawn, and the
    one fix is in record.json itself.
    """
    from edc_bench.errors import ConfigError

    if isinstance(record, dict):
        for name, value in record.items():
            _check_text(value, folder, f"{key}.{name}" if key != "record" else str(name))
    elif isinstance(record, list):
        for value in record:
            _check_text(value, folder, key)
    elif isinstance(record, str):
        try:
            record.encode("utf-8")
        except UnicodeEncodeError:
            shown = record.encode("utf-8", "backslashreplace").decode("utf-8")
            raise ConfigError(f"{folder}/record.json: {key} {shown!r} is not valid text (bytes that are not "
                              "UTF-8); correct it in record.json, then draw the report again") from None
