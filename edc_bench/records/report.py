"""The report of a test: two A4 pages in one PDF for printing, and each page as a PNG for screens and mail.

Page 1 is for the customer and the shop: who tested (station, operator),
what (pump type, part number, pump serial, valve), when (local time with
its offset from UTC), the verdict in large type with what to do, the
valve's point against the boundary between reusable and worn valves
(the one chart: the rack's trace told a customer nothing), all in plain
words. Page 2 is for the engineer: the parameter table with uncertainties and references
(the new-valve baseline for af and a1, the data-sheet nominal for the
others, as the paper's Table 1 compares valves), the classifier (model,
file, SHA-256, P(faulty), distance), baseline, coil, test and timing,
model fit, versions, the record's folder, and the convergence and
tracking-error plots.

Drawn with matplotlib from the record folder alone (record.json and the
trace; no variant file, no model, no recomputation). Every text is fitted
to its box by measured width (:mod:`~edc_bench.records.report_layout`).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.backends.backend_pdf import PdfPages

from edc_bench.paths import atomic_write
from edc_bench.records import report_content as content
from edc_bench.records import report_plots as plots
from edc_bench.records.reader import load_record, load_trace
from edc_bench.records.retest_link import find_retest
from edc_bench.records.report_layout import (
    CONTENT_WIDTH_PT,
    GREY,
    MARGIN_PT,
    PAGE_HEIGHT_PT,
    PAGE_WIDTH_PT,
    Page,
    Rows,
    block_height_pt,
    fit_rows,
    fit_text,
    key_value_rows,
    line_pitch_pt,
)
from edc_bench.verdict.part_words import part_line
from edc_bench.records.schema import Record
from edc_bench.verdict.verdicts import Verdict

REPORT_PDF = "report.pdf"
REPORT_PNG = "report-page.png"  # page 1, the customer's page (the name the docs and older scripts use)
REPORT_PNG_PAGE_2 = "report-page-2.png"
REPORT_PNGS = (REPORT_PNG, REPORT_PNG_PAGE_2)
PNG_DPI = 110
_RIGHT_PT = PAGE_WIDTH_PT - MARGIN_PT
_TOP_PT = 40.0
_FOOTER_BASELINE_PT = PAGE_HEIGHT_PT - 34.0
_PLOT_LEFT_PT = MARGIN_PT + 44.0  # room for the y tick labels and the axis label
_PLOT_BELOW_PT = 34.0  # the x tick labels and the axis label under a plot
_BADGE_TEXT = {Verdict.MARGINAL: "black"}  # dark words on the amber badge; white on the others
_IDENTITY_PT, _IDENTITY_MIN_PT = 9.0, 6.5  # identities shrink before they are shortened: 100 characters fit whole
_DETAIL_SIZES_PT = (7.5, 7.0, 6.5)  # page 2's text, set smaller while it leaves the plots too little room
_DETAIL_MIN_PT = 6.5  # the smallest a long value on page 2 is set before it is shortened
_MIN_PLOT_PT = 110.0


def draw_report(folder: Path, out_dir: Path | None = None, history_note: str | None = None, pngs: bool = True
                ) -> tuple[Path, tuple[Path, ...]]:
    """Draw the report of the record in ``folder``.

    Parameters
    ----------
    folder : pathlib.Path
        A record folder written by ``edc-bench test``.
    out_dir : pathlib.Path, optional
        Where to write (default: the record folder).
    history_note : str, optional
        The test's entry in the history and its chain hash (:meth:`~edc_bench.history.standing.Standing.note`),
        printed in page 1's footer: the customer's copy keeps an anchor of the history outside the station.
    pngs : bool
        Also write each page as PNG (the web view serves the PDF alone).

    Returns
    -------
    (pathlib.Path, tuple of pathlib.Path)
        The two-page PDF, and one PNG per page (page 1 first: ``report-page.png``; none without ``pngs``).
    """
    folder = Path(folder)
    record = load_record(folder)
    retested_by = find_retest(folder, record)  # a MARGINAL's report names what it and its retest decide
    if retested_by is not None:
        record = record.model_copy(update={"retested_by": retested_by})
    trace = load_trace(folder)
    out_dir = Path(out_dir) if out_dir is not None else folder
    out_dir.mkdir(parents=True, exist_ok=True)
    pages = report_pages(record, trace, folder.name, history_note)
    pdf = write_pdf(pages, record, out_dir / REPORT_PDF)
    if not pngs:
        return pdf, ()
    written = tuple(out_dir / name for name in REPORT_PNGS)
    for page, png in zip(pages, written, strict=True):
        atomic_write(png, lambda f, page=page: page.figure.savefig(f, format="png", dpi=PNG_DPI))
    return pdf, written


def report_pages(record: Record, trace: dict[str, np.ndarray], folder_name: str,
                 history_note: str | None = None) -> list[Page]:
    """The two pages, drawn and not yet written: the customer's and the engineer's."""
    return [customer_page(record, trace, folder_name, history_note), engineer_page(record, trace, folder_name)]


def write_pdf(pages: list[Page], record: Record, path: Path) -> Path:
    """Write ``pages`` as one PDF at ``path`` (atomically) and return it."""
    import matplotlib

    metadata = {"Title": f"Solenoid valve test report: {record.valve_id or 'valve'}, {record.verdict}",
                "Creator": f"edc-bench {record.software_version or ''}".strip()}

    def write(file: Any) -> None:
        with PdfPages(file, metadata=metadata) as pdf:
            for page in pages:
                pdf.savefig(page.figure)

    with matplotlib.rc_context({"pdf.fonttype": 42}):  # TrueType: the words are text a reader can select and search
        atomic_write(path, write)
    return path


# --- page 1: the customer's ---------------------------------------------------------------------------------------


def customer_page(record: Record, trace: dict[str, np.ndarray], folder_name: str,
                  history_note: str | None = None) -> Page:
    """Who, what, when, the verdict and what to do, and one chart: this valve against the limit.

    The rack's trace against the test command is not on it: it looks the same for a sound valve and a worn one and
    told a customer nothing (the engineer's page shows the tracking error; the record keeps the trace).
    """
    page = Page()
    y = _header(page, "Solenoid valve test report", 1)
    y = _identity(page, record, y + 10.0)
    page.rule(y + 9.0)
    y = _verdict(page, record, y + 18.0)
    page.rule(y + 9.0)
    _decision(page, record, y + 18.0)
    # the history's hash before the folder's name: a long valve id in the name can only cut the line's end
    _footer(page, f"Technical details on page 2  \u00b7  edc-bench {record.software_version or '?'}  \u00b7  "
                  + (f"{history_note}  \u00b7  " if history_note else "") + f"record {folder_name}")
    return page


def _header(page: Page, title: str, number: int) -> float:
    """The page's title and number; returns the y of the rule under them."""
    size = 17.0 if number == 1 else 14.0
    fitted = fit_text(title, CONTENT_WIDTH_PT - 60.0, size, bold=True, min_size_pt=11.0)
    bottom = page.lines(MARGIN_PT, _TOP_PT, fitted, bold=True)
    page.text(_RIGHT_PT, _TOP_PT + 0.74 * fitted.size_pt, f"page {number} of 2", 8.0, colour=GREY, align="right")
    page.rule(bottom + 6.0, colour="0.3")
    return bottom + 6.0


def _footer(page: Page, text: str) -> None:
    fitted = fit_text(text, CONTENT_WIDTH_PT, 7.0, min_size_pt=6.0)
    page.text(MARGIN_PT, _FOOTER_BASELINE_PT, fitted.lines[0], fitted.size_pt, colour=GREY)


def _identity(page: Page, record: Record, top_pt: float) -> float:
    """Two columns: the test (date, station, operator) and the pump and valve; returns their bottom."""
    column_pt = (CONTENT_WIDTH_PT - 14.0) / 2
    common = {"size_pt": _IDENTITY_PT, "max_lines": 4, "min_size_pt": _IDENTITY_MIN_PT}
    left = key_value_rows(page, MARGIN_PT, top_pt, content.test_rows(record), label_width_pt=62.0,
                          value_width_pt=column_pt - 62.0, **common)
    right = key_value_rows(page, MARGIN_PT + column_pt + 14.0, top_pt, content.pump_rows(record),
                           label_width_pt=74.0, value_width_pt=column_pt - 74.0, **common)
    return max(left, right)


def _verdict(page: Page, record: Record, top_pt: float) -> float:
    """The verdict on a coloured badge, what to do beside it in large type, the findings under that."""
    badge_pt, gap_pt = 150.0, 16.0
    shown = content.shown_verdict(record)  # a retest's decision
    word = fit_text(shown, badge_pt - 16.0, 30.0, min_size_pt=12.0, bold=True)
    text_x, text_width = MARGIN_PT + badge_pt + gap_pt, CONTENT_WIDTH_PT - badge_pt - gap_pt
    y = page.lines(text_x, top_pt, fit_text(content.advice_sentence(record), text_width, 15.0, max_lines=3,
                                             min_size_pt=9.0, bold=True), bold=True)
    for line in content.findings(record):
        y = page.lines(text_x, y + 7.0, fit_text(line, text_width, 9.0, max_lines=4, min_size_pt=8.0))
    height = max(y - top_pt, 58.0)
    page.box(MARGIN_PT, top_pt, badge_pt, height, plots.VERDICT_COLOURS.get(shown, "0.45"))
    word_top = top_pt + (height - word.height_pt) / 2
    page.lines(MARGIN_PT + badge_pt / 2, word_top, word, bold=True,
               colour=_BADGE_TEXT.get(shown, "white"), align="center")
    return top_pt + height


def _plot_title(page: Page, x_pt: float, top_pt: float, title: str, width_pt: float, size_pt: float = 10.0) -> float:
    """A plot's title, fitted to the plot's width; returns where the plot may start."""
    return page.lines(x_pt, top_pt, fit_text(title, width_pt, size_pt, min_size_pt=8.0), bold=True) + 7.0


#: the chart's largest side: beside it the legend (its longest entry "this valve: MARGINAL (tested twice: FAIL)") and
#: the caption keep a column of their own
_DECISION_MAX_PT = 280.0


def _decision(page: Page, record: Record, top_pt: float) -> None:
    """The valve against the boundary, as large as the page's room allows, its legend and a few plain sentences
    beside it (or, for a test not judged, why there is no chart)."""
    y = _plot_title(page, MARGIN_PT, top_pt, "This valve compared with new valves and worn valves", CONTENT_WIDTH_PT)
    bottom_pt = _FOOTER_BASELINE_PT - 12.0 - _PLOT_BELOW_PT
    if record.classification is None or record.decision_plane is None:
        why = ("The test did not judge the valve, so there is nothing to compare." if record.classification is None
               else "This record holds no chart of new and worn valves to compare with.")
        page.paragraph(MARGIN_PT, y, why, CONTENT_WIDTH_PT, 9.0, colour=GREY)
        return
    size_pt = float(np.clip(bottom_pt - y, 120.0, _DECISION_MAX_PT))
    ax = page.axes(_PLOT_LEFT_PT, y, size_pt, size_pt)
    entries = plots.draw_decision(ax, record)
    side_x = _PLOT_LEFT_PT + size_pt + 18.0
    side_width = _RIGHT_PT - side_x
    legend = page.figure.legend([h for h, _ in entries], [w for _, w in entries], loc="upper left",
                                bbox_to_anchor=(side_x / PAGE_WIDTH_PT, 1.0 - y / PAGE_HEIGHT_PT), frameon=False,
                                fontsize=plots.LEGEND_PT, borderaxespad=0.0, borderpad=0.0, handlelength=1.8,
                                labelspacing=0.7)
    legend.set_in_layout(False)
    legend_height_pt = len(entries) * plots.LEGEND_PT * 1.7 + 6.0  # rows of text and spacing, with room to spare
    caption = ("The test measures the valve's friction (af) and damping (a1) and divides them by a new valve's. "
               "A valve on the green side of the line is fit to use again; on the red side it is worn. In the grey "
               "band the two cannot be told apart with certainty: test the valve again.")
    room = _FOOTER_BASELINE_PT - 12.0 - (y + legend_height_pt + 10.0)
    lines = max(int((room - 8.0) // line_pitch_pt(8.0)), 1)
    page.paragraph(side_x, y + legend_height_pt + 10.0, caption, side_width, 8.0, max_lines=lines, colour=GREY)


# --- page 2: the engineer's ---------------------------------------------------------------------------------------


def engineer_page(record: Record, trace: dict[str, np.ndarray], folder_name: str) -> Page:
    """Every figure behind the verdict, as record.json holds it, and the convergence and tracking-error plots.

    The text is set at 7.5 pt, or smaller (down to 6.5 pt) when a long
    record (a model that does not fit explains at length) would leave the
    plots too little room.
    """
    for size_pt in _DETAIL_SIZES_PT:
        page = Page()
        y = _engineer_text(page, record, folder_name, size_pt)
        if _plot_room_pt(y + 14.0) >= _MIN_PLOT_PT:
            break
    _engineer_plots(page, record, trace, y + 14.0)
    _footer(page, f"Page 2 of 2  \u00b7  record {folder_name}")
    return page


def _engineer_text(page: Page, record: Record, folder_name: str, size_pt: float) -> float:
    """Page 2's header, parameter table, sections and reasons at ``size_pt``; returns their bottom."""
    y = _header(page, "Solenoid valve test report: technical details", 2)
    rows = [("Valve", record.valve_id or "-"),
            ("Verdict", f"{record.verdict}, tested {content.local_time(record.started_at)}"),
            ("Part at fault", part_line(record.part)),
            ("Record folder", folder_name)]
    if record.retest is not None:  # the pair's decision, the rule that made it and the first test's record
        rows.append(("Retest of", f"{record.retest.of_record} ({record.retest.of_verdict or '?'}); decision "
                                  f"{record.retest.decision or '?'} by {record.retest.rule}"))
    y = key_value_rows(page, MARGIN_PT, y + 8.0, rows, label_width_pt=70.0, value_width_pt=CONTENT_WIDTH_PT - 70.0,
        size_pt=size_pt, max_lines=2, min_size_pt=min(size_pt, _DETAIL_MIN_PT))
    y = _parameter_table(page, record, y + 14.0, size_pt)
    column_pt = (CONTENT_WIDTH_PT - 16.0) / 2

    def section(title: str, rows: list[tuple[str, str]]) -> tuple[str, Rows]:
        return title, fit_rows(rows, label_width_pt=70.0, value_width_pt=column_pt - 70.0, size_pt=size_pt,
                               max_lines=4, min_size_pt=min(size_pt, _DETAIL_MIN_PT),
                               mono_labels=frozenset({"SHA-256", "Training data"}))

    left = [section("Classifier", content.classifier_rows(record)), section("Baseline", content.baseline_rows(record)),
            section("Coil", content.coil_rows(record))]
    right = [section("Test", content.test_details_rows(record)),
             section("Model fit", content.model_fit_rows(record))]
    # the part at fault under the shorter column (a model that does not fit makes the right one long)
    (left if _sections_height_pt(left) <= _sections_height_pt(right) else right).append(
        section("Which part is at fault", content.part_rows(record)))
    # the timing under the shorter column: a model that does not fit makes the right one long
    shorter = left if _sections_height_pt(left) <= _sections_height_pt(right) else right
    shorter.append(section("Timing", content.timing_rows(record)))
    bottom = max(_draw_sections(page, MARGIN_PT, y + 14.0, column_pt, left),
                 _draw_sections(page, MARGIN_PT + column_pt + 16.0, y + 14.0, column_pt, right))
    return _reasons(page, record, bottom + 14.0, size_pt)


def _plot_room_pt(top_pt: float) -> float:
    """The height page 2's plots get below ``top_pt``: their titles above them, their labels below."""
    return _FOOTER_BASELINE_PT - 14.0 - _PLOT_BELOW_PT - (top_pt + block_height_pt(1, 9.0) + 7.0)


_SECTION_GAP_PT = 14.0
_HEADING_PT = 9.5


def _section_heading(page: Page, x_pt: float, top_pt: float, title: str, width_pt: float) -> float:
    bottom = page.lines(x_pt, top_pt, fit_text(title, width_pt, _HEADING_PT, bold=True), bold=True)
    page.rule(bottom + 3.0, x_pt, x_pt + width_pt, colour="0.75")
    return bottom + 8.0


def _sections_height_pt(sections: list[tuple[str, Rows]]) -> float:
    heading_pt = block_height_pt(1, _HEADING_PT) + 8.0
    return sum(heading_pt + rows.height_pt + _SECTION_GAP_PT for _, rows in sections)


def _draw_sections(page: Page, x_pt: float, top_pt: float, width_pt: float,
                   sections: list[tuple[str, Rows]]) -> float:
    """Headed groups of label and value rows, one under the other; returns their bottom."""
    y = top_pt
    for title, rows in sections:
        y = rows.draw(page, x_pt, _section_heading(page, x_pt, y, title, width_pt)) + _SECTION_GAP_PT
    return y - _SECTION_GAP_PT


_TABLE_COLUMNS = (("parameter", 62.0), ("unit", 64.0), ("identified", 72.0), ("\u00b1 1 sd", 62.0),
                  ("reference", 72.0), ("reference from", 96.0), ("change", 82.0))


def _parameter_table(page: Page, record: Record, top_pt: float, size_pt: float) -> float:
    """The identified parameters with their standard errors, references and change; returns its bottom."""
    y = _section_heading(page, MARGIN_PT, top_pt, "Identified parameters (referred to the reference coil; af and a1 "
                                                  "are the diagnosis features)", CONTENT_WIDTH_PT)
    rows = content.parameter_rows(record)
    if not rows:
        return page.paragraph(MARGIN_PT, y, "No parameters: the test stopped before identifying any.",
                              CONTENT_WIDTH_PT, size_pt)
    y = _table_row(page, y, [name for name, _ in _TABLE_COLUMNS], size_pt, bold=True)
    for row in rows:
        y = _table_row(page, y + 3.0, row, size_pt)
    return y


def _table_row(page: Page, top_pt: float, cells: list[str], size_pt: float, *, bold: bool = False) -> float:
    x = MARGIN_PT
    for text, (_, width) in zip(cells, _TABLE_COLUMNS, strict=True):
        page.lines(x, top_pt, fit_text(text, width - 6.0, size_pt, bold=bold), bold=bold)
        x += width
    return top_pt + block_height_pt(1, size_pt)


def _reasons(page: Page, record: Record, top_pt: float, size_pt: float) -> float:
    """The verdict's reasons and the test's problems, across the page; returns their bottom."""
    lines = content.reason_lines(record)
    if not lines:
        return top_pt - _SECTION_GAP_PT
    y = _section_heading(page, MARGIN_PT, top_pt, "Reasons", CONTENT_WIDTH_PT)
    for n, line in enumerate(lines[:6]):  # each whole, up to 6 lines (a model that does not fit explains at length)
        y = page.lines(MARGIN_PT, y + (4.0 if n else 0.0),
                       fit_text(line, CONTENT_WIDTH_PT, size_pt, max_lines=6, min_size_pt=min(size_pt, 6.0)))
    return y


def _engineer_plots(page: Page, record: Record, trace: dict[str, np.ndarray], top_pt: float) -> None:
    """The convergence of af and a1 and the tracking error, side by side, down to the footer (or, on a page the
    text has filled, a line saying where they are)."""
    if _plot_room_pt(top_pt) < _MIN_PLOT_PT:  # smaller, their axis labels run into their titles
        page.paragraph(MARGIN_PT, top_pt, "No room left on this page for the convergence and tracking-error plots; "
                       "the record's trace.mf4 holds their data.", CONTENT_WIDTH_PT, 7.5, max_lines=2, colour=GREY)
        return
    gap_pt, label_pt = 34.0, 40.0
    width_pt = (CONTENT_WIDTH_PT - gap_pt) / 2 - label_pt
    left_x = MARGIN_PT
    right_x = MARGIN_PT + (CONTENT_WIDTH_PT + gap_pt) / 2
    y_left = _plot_title(page, left_x, top_pt, "Estimates of af and a1 during the test",
                         width_pt + label_pt, 9.0)
    y_right = _plot_title(page, right_x, top_pt, "Tracking error over the whole test", width_pt + label_pt, 9.0)
    y = max(y_left, y_right)
    height_pt = min(_FOOTER_BASELINE_PT - 14.0 - _PLOT_BELOW_PT - y, 200.0)
    plots.draw_convergence(page.axes(left_x + label_pt, y, width_pt, height_pt), trace, record)
    plots.draw_tracking_error(page.axes(right_x + label_pt, y, width_pt, height_pt), trace)


__all__ = ["REPORT_PDF", "REPORT_PNG", "REPORT_PNGS", "REPORT_PNG_PAGE_2", "customer_page", "draw_report",
           "engineer_page", "report_pages", "write_pdf"]
