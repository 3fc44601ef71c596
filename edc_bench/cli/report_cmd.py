"""``edc-bench report``: the two-page printable report of a test (the customer's page and the engineer's)."""

from __future__ import annotations

import argparse
import os
import shutil
import tempfile
from pathlib import Path
from typing import TYPE_CHECKING

from edc_bench.cli.common import given_path

if TYPE_CHECKING:
    from edc_bench.records.schema import Record


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Register the command."""
    p = sub.add_parser(
        "report", help="two-page report of a test (PDF, and a PNG per page)",
        description="Draw the report of a record folder. Page 1, for the customer: station, operator, pump, "
                    "valve, date, the verdict and what to do, the tracking plot and the valve against the "
                    "boundary. Page 2, for the engineer: the parameter table against the baseline, the classifier "
                    "(model, file, SHA-256, P(faulty), distance), baseline, coil, timing, model fit, versions and "
                    "the convergence and tracking-error plots. Writes report.pdf (both pages), report-page.png "
                    "(page 1) and report-page-2.png into the record folder (or --out). A record changed since its "
                    "test, or whose verdict does not follow from its own figures (problems, classification, "
                    "features, baseline), is refused, naming what disagrees.",
    )
    p.add_argument("record_dir", type=given_path, help="a record folder written by 'edc-bench test'")
    p.add_argument("--out", type=given_path, default=None, metavar="DIR", help="folder for the report (default: the record's)")
    from edc_bench.cli.common import add_history_db_argument

    add_history_db_argument(p, "where the test's chain hash is looked up (page 1 prints it), and the record held to "
                               "the one first indexed: ")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    """Draw and say where."""
    from edc_bench.cli.common import check_output_folder, probe_writable
    from edc_bench.errors import ConfigError
    from edc_bench.records.consistency import disagreements, refusal
    from edc_bench.records.reader import load_record
    from edc_bench.records.report import draw_report
    from edc_bench.runtime.signals import settle

    record = load_record(args.record_dir)  # a folder that is not a record, or changed since its test, ...
    _check_text(record, args.record_dir)  # ... text that cannot be drawn, ...
    if args.out is not None:
        check_output_folder(args.out, "--out")  # ... an --out that cannot take the report, ...
    else:
        probe_writable(args.record_dir, f"{args.record_dir}: the record folder is not writable; write the report "
                                        "elsewhere with --out DIR")
    found = disagreements(record)
    if found:  # ... and a verdict that does not follow from the record's own figures, refused before drawing
        raise ConfigError(refusal(args.record_dir, record, found, "no report drawn"))
    from edc_bench.history.standing import history_standing

    standing = history_standing(record, args.record_dir, args.db)
    if standing is not None and standing.differs:  # ... or a record that is not the one the history first indexed
        raise ConfigError(f"{args.record_dir}: {standing.differs}: no report drawn; 'edc-bench history --audit "
                          f"{record.valve_id}' shows the test as indexed")
    out_dir = Path(args.record_dir if args.out is None else args.out)
    out_dir.mkdir(parents=True, exist_ok=True)
    # drawn beside, then put in place: an interrupt, or a library's error made of one, leaves the report that was
    # there as it was (a report half replaced would pass for the whole of one)
    drawing = Path(tempfile.mkdtemp(prefix=".report-", dir=out_dir))
    try:
        drawn_pdf, drawn_pngs = draw_report(args.record_dir, drawing, None if standing is None else standing.note())
        settle()  # Ctrl-C that a library swallowed while drawing is still Ctrl-C; one after this is only noted
        pdf, pngs = out_dir / drawn_pdf.name, tuple(out_dir / png.name for png in drawn_pngs)
        for drawn, placed in zip((drawn_pdf, *drawn_pngs), (pdf, *pngs), strict=True):
            os.replace(drawn, placed)
    except OSError as exc:  # named as the file it was to be (a full disk's one line), not the drawing folder's
        if exc.filename is not None and Path(exc.filename).parent == drawing:
            raise OSError(exc.errno, exc.strerror, str(out_dir / Path(exc.filename).name)) from exc
        raise
    finally:
        shutil.rmtree(drawing, ignore_errors=True)
    print(f"report: {pdf}\npage images: {', '.join(map(str, pngs))}"
          + ("" if standing is None else f"\nhistory: {standing.note()} (printed on page 1)"))
    return 0


def _check_text(record: Record, folder: Path) -> None:
    """Refuse a record holding text that is not valid Unicode (hand-edited, or bytes an older edc-bench kept).

    The report draws the record's text; such text cannot be drawn, and the
    one fix is in record.json itself.
    """
    _check_text_in(record.model_dump(by_alias=True), folder, "record")


def _check_text_in(value: object, folder: Path, key: str) -> None:
    from edc_bench.errors import ConfigError

    if isinstance(value, dict):
        for name, item in value.items():
            _check_text_in(item, folder, f"{key}.{name}" if key != "record" else str(name))
    elif isinstance(value, (list, tuple)):
        for item in value:
            _check_text_in(item, folder, key)
    elif isinstance(value, str):
        try:
            value.encode("utf-8")
        except UnicodeEncodeError:
            shown = value.encode("utf-8", "backslashreplace").decode("utf-8")
            raise ConfigError(f"{folder}/record.json: {key} {shown!r} is not valid text (bytes that are not "
                              "UTF-8); correct it in record.json, then draw the report again") from None
