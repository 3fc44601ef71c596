"""No text of the report leaves its box: every word of report.pdf, as a PDF reader finds it, lies inside the page's
margins and keeps clear of every other word, for a PASS, a FAIL, a MARGINAL, an aborted (INVALID) test and a
record whose identities are as long as the command line takes.

The words and their boxes come from the PDF itself (pdfminer.six reads what was drawn, with the embedded font's
metrics), not from matplotlib's own idea of where it put them: the paper a customer is given is what is checked.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, replace
from datetime import datetime, timedelta, timezone
from functools import lru_cache
from pathlib import Path
from typing import Any

import pytest
from pdfminer.converter import PDFLayoutAnalyzer
from pdfminer.layout import LTChar
from pdfminer.pdfdocument import PDFDocument
from pdfminer.pdfinterp import PDFPageInterpreter, PDFResourceManager
from pdfminer.pdfpage import PDFPage
from pdfminer.pdfparser import PDFParser

from edc_bench.bench import BenchOptions, run_bench_test, run_simulated_test
from edc_bench.config import load_variant
from edc_bench.records.reader import load_record, load_trace
from edc_bench.records.record import write_record
from edc_bench.records.report import REPORT_PDF, report_pages, write_pdf
from edc_bench.records.schema import Identity
from edc_bench.testing.faults import FaultyBus, Rule
from edc_bench.verdict.verdicts import Verdict

MARGIN_PT = 28.35  # 10 mm: inside what any office printer prints, with room to spare
CLEARANCE_PT = 1.0  # each word's box grown by this: two words of different texts at least 2 pt apart (a space
# of 7 pt text is 2.2 pt): a label run into its value, or a wrapped line onto the next row, fails

IDENTITY = {"pump_serial": "PS-20231", "station": "bench-2", "operator": "m.keller", "job_ref": "JOB-004711"}
# as long as `edc-bench test` takes them (100 characters), with spaces and without, and wide letters
LONG_IDENTITY = {
    "pump_serial": "SN-" + "W8M0" * 24 + "X",
    "station": "Werkstatt Musterstadt Nord, Halle 3, Prüfstand für Verteilereinspritzpumpen Nr. 2 (links hinten)",
    "operator": "Maximilian Alexander Oberhuber-Wittgenstein-Schwarzenberg, Meister, Abteilung Einspritztechnik",
    "job_ref": "Auftrag 2026-11-28/0815, Fahrzeug WDB9066331S123456, Kunde Spedition Müller & Söhne GmbH, Halle",
}
LONG_VALVE_ID = "MV-" + "WWMW" * 24 + "W"


@dataclass(frozen=True)
class Word:
    """A word of the PDF as drawn: its page, text, box in points (origin bottom left) and text object."""

    page: int
    text: str
    x0: float
    y0: float
    x1: float
    y1: float
    text_object: int

    def clashes(self, other: Word, clearance_pt: float) -> bool:
        """The two boxes, each grown by ``clearance_pt``, overlap."""
        return (self.page == other.page and self.x0 - clearance_pt < other.x1 + clearance_pt
                and other.x0 - clearance_pt < self.x1 + clearance_pt
                and self.y0 - clearance_pt < other.y1 + clearance_pt
                and other.y0 - clearance_pt < self.y1 + clearance_pt)

    def __str__(self) -> str:
        return f"p{self.page} {self.text!r} at ({self.x0:.1f}, {self.y0:.1f})-({self.x1:.1f}, {self.y1:.1f}) pt"


class _CharsByTextObject(PDFLayoutAnalyzer):
    """Keeps every character drawn, grouped by the PDF text object (BT ... ET) that drew it."""

    def __init__(self, resources: PDFResourceManager) -> None:
        super().__init__(resources, laparams=None)
        self.text_objects: list[list[LTChar]] = [[]]

    def render_char(self, *args: Any, **kwargs: Any) -> float:
        advance = super().render_char(*args, **kwargs)
        self.text_objects[-1].append(self.cur_item._objs[-1])  # the LTChar just made, with its box
        return advance


class _Interpreter(PDFPageInterpreter):
    def do_BT(self) -> None:  # matplotlib draws each line of each text in a text object of its own
        self.device.text_objects.append([])
        super().do_BT()


@lru_cache(maxsize=8)
def pdf_words(path: Path) -> tuple[list[Word], list[tuple[float, float, float, float]]]:
    """Every word of the PDF (characters of one text object between spaces) and each page's box (read once per
    file: the tests below read the same reports)."""
    words: list[Word] = []
    pages = []
    with path.open("rb") as file:
        document = PDFDocument(PDFParser(file))
        resources = PDFResourceManager()
        for number, page in enumerate(PDFPage.create_pages(document), start=1):
            pages.append(tuple(page.mediabox))
            device = _CharsByTextObject(resources)
            _Interpreter(resources, device).process_page(page)
            for n, chars in enumerate(device.text_objects):
                words += _split_words(chars, number, n)
    return words, pages


def _split_words(chars: list[LTChar], page: int, text_object: int) -> list[Word]:
    words, run = [], []
    for char in [*chars, None]:
        if char is not None and not char.get_text().isspace():
            run.append(char)
            continue
        if run:
            words.append(Word(page, "".join(c.get_text() for c in run), min(c.x0 for c in run),
                              min(c.y0 for c in run), max(c.x1 for c in run), max(c.y1 for c in run), text_object))
        run = []
    return words


def layout_problems(words: list[Word], pages: list[tuple[float, float, float, float]]) -> list[str]:
    """Words outside the margins, and pairs of words of different text objects closer than the clearance."""
    problems = []
    for word in words:
        x0, y0, x1, y1 = pages[word.page - 1]
        if (word.x0 < x0 + MARGIN_PT or word.x1 > x1 - MARGIN_PT or word.y0 < y0 + MARGIN_PT
                or word.y1 > y1 - MARGIN_PT):
            problems.append(f"outside the margins: {word}")
    ordered = sorted(words, key=lambda w: (w.page, w.x0))
    for n, a in enumerate(ordered):  # a sweep from left to right: only words that reach each other are compared
        for b in ordered[n + 1:]:
            if b.page != a.page or b.x0 - CLEARANCE_PT >= a.x1 + CLEARANCE_PT:
                break
            if a.text_object != b.text_object and a.clashes(b, CLEARANCE_PT):
                problems.append(f"too close: {a} and {b}")
    return problems


@pytest.fixture(scope="module")
def report_of(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Callable[[str], Path]]:
    """The report PDF of a record of each kind, each drawn once for the module, when first asked for."""
    from conftest import simulated_bench_factory

    out = tmp_path_factory.mktemp("report-layout")
    variant = load_variant()
    drawn: dict[str, Path] = {}
    results: dict[str, Any] = {}
    with simulated_bench_factory() as simulated_bench:
        def aborted() -> Any:  # the bus cut at 4 s: INVALID, with its abort's advice
            bench, clock, _ = simulated_bench(variant, "new", 3)
            return run_bench_test(FaultyBus(bench, clock.now_s, [Rule("cut", 4.0)]), clock, variant,
                                  BenchOptions(check_gains=False, identity=Identity(**IDENTITY)))

        tests: dict[str, tuple[Callable[[], Any], Verdict]] = {
            "pass": (lambda: run_simulated_test(variant, "new", 3, identity=Identity(**IDENTITY)), Verdict.PASS),
            "fail": (lambda: run_simulated_test(variant, "worn", 2, identity=Identity(**IDENTITY)), Verdict.FAIL),
            "marginal": (lambda: run_simulated_test(variant, "clearance=0.185", 0, identity=Identity(**IDENTITY)),
                         Verdict.MARGINAL),
            "invalid": (aborted, Verdict.INVALID),
            # a sound valve in a pump whose rack binds (#67): the part at fault on both pages
            "rack": (lambda: run_simulated_test(variant, "new", 3, rack_fault="bind", identity=Identity(**IDENTITY)),
                     Verdict.INVALID),
            # the FAIL's test as if the ids had been typed this long (one simulation fewer)
            "long values": (lambda: replace(result_of("fail"), identity=Identity(**LONG_IDENTITY), valve_id=LONG_VALVE_ID),
                            Verdict.FAIL),
            # the MARGINAL's test as the retest of another MARGINAL: page 1 gives the pair's decision
            "retest": (lambda: result_of("marginal"), Verdict.MARGINAL),
        }

        def result_of(kind: str) -> Any:
            if kind not in results:
                run, verdict = tests[kind]
                results[kind] = run()
                assert results[kind].verdict == verdict, (kind, results[kind].verdict)
            return results[kind]

        def report(kind: str) -> Path:
            if kind not in drawn:
                result = result_of(kind)
                folder = write_record(result, out / kind.replace(" ", "-"), figure=False,
                                      retest=RETEST if kind == "retest" else None)
                record = load_record(folder)
                with local_time_zone(TIME_ZONE):  # the pages draw draw_report's, without its PNGs (test_report.py)
                    pages = report_pages(record, load_trace(folder), folder.name)
                drawn[kind] = write_pdf(pages, record, folder / REPORT_PDF)
            return drawn[kind]

        yield report


RETEST = {"of_record": "20261126T102811-p-edc-default-clearance_0.185", "of_verdict": "MARGINAL",
          "decision": "FAIL", "words": "near the limit twice: replace the valve",
          "rule": "retest.decide.MARGINAL = FAIL"}
TIME_ZONE = "IST-5:30"  # the reports are drawn on a machine half an hour off a whole-hour zone (POSIX TZ: no tz data)


class local_time_zone:  # noqa: N801  (a context manager named as it reads)
    """This process's local time zone set to ``zone`` inside the block, and back afterwards."""

    def __init__(self, zone: str) -> None:
        self.zone, self.before = zone, os.environ.get("TZ")

    def __enter__(self) -> None:
        os.environ["TZ"] = self.zone
        time.tzset()

    def __exit__(self, *exc: object) -> None:
        if self.before is None:
            os.environ.pop("TZ", None)
        else:
            os.environ["TZ"] = self.before
        time.tzset()


# pass, invalid and the retest in CI's slow pass: the default suite stays under 5 minutes
@pytest.mark.parametrize("kind", [pytest.param("pass", marks=pytest.mark.slow), "fail", "marginal",
                                  pytest.param("invalid", marks=pytest.mark.slow), "long values",
                                  pytest.param("retest", marks=pytest.mark.slow),
                                  pytest.param("rack", marks=pytest.mark.slow)])
def test_no_word_leaves_the_page_or_runs_into_another(report_of: Callable[[str], Path], kind: str) -> None:
    words, pages = pdf_words(report_of(kind))
    assert len(words) > 100  # the PDF's text is there to be read (not drawn as paths)
    problems = layout_problems(words, pages)
    assert not problems, f"{len(problems)} problems, the first 15:\n" + "\n".join(problems[:15])


def test_the_check_finds_a_label_run_into_its_value_and_a_word_off_the_page() -> None:
    """The check itself: words less than a space apart, or past the margin, are found; a space apart is fine."""
    label = Word(1, "operator", 53.0, 700.0, 129.0, 707.5, 1)
    pages = [(0.0, 0.0, 595.0, 842.0)]
    assert layout_problems([label, Word(1, "bench-2", 129.3, 700.0, 160.0, 707.5, 2)], pages)
    assert not layout_problems([label, Word(1, "bench-2", 131.5, 700.0, 160.0, 707.5, 2)], pages)
    assert not layout_problems([label, Word(1, "bench-2", 129.3, 700.0, 160.0, 707.5, 1)], pages)  # one text
    assert layout_problems([Word(1, "baseline", 560.0, 700.0, 600.0, 707.5, 1)], pages)


def page_text(pdf: Path, page: int) -> str:
    """The words of one page in the order drawn, one space between."""
    words, _ = pdf_words(pdf)
    return " ".join(word.text for word in words if word.page == page)


def test_page_1_tells_the_customer_who_what_when_the_verdict_and_what_to_do_in_plain_words(
        report_of: Callable[[str], Path]) -> None:
    pdf = report_of("fail")
    text = page_text(pdf, 1)
    folder = pdf.parent
    record = load_record(folder)
    for shown in ("bench-2", "m.keller", "PE-EDC-0001", "PS-20231", "worn", "FAIL",
                  "Worn valve or a dragging rack: check by hand that the rack moves freely, then replace the valve.",
                  "Job / vehicle JOB-004711"):
        assert shown in text, shown
    started = datetime.fromisoformat(record.started_at)
    local = started.astimezone(timezone(timedelta(hours=5, minutes=30)))
    assert f"{local:%Y-%m-%d %H:%M} (UTC+05:30)" in text  # the machine's local time, not UTC
    # one chart: the valve against the limit; the rack's trace, the same for a sound and a worn valve, is not on it
    assert "This valve compared with new valves and worn valves" in text and "Rack position" not in text
    for engineers_words in ("Fig", "P(faulty)", "distance", "boundary", "sha256", "SHA-256", "UTC "):
        assert engineers_words not in text, engineers_words
    assert record.classification.model_sha256[:8] not in text.replace(" ", "")


def test_page_2_holds_every_figure_the_engineer_asks_for(report_of: Callable[[str], Path]) -> None:
    pdf = report_of("fail")
    text = page_text(pdf, 2)
    record = load_record(pdf.parent)
    unbroken = text.replace(" ", "")  # digests and the folder's name may be broken across lines
    cls = record.classification
    for shown in ("P(faulty)", f"{cls.probability_faulty:.4f}", f"{cls.distance:+.4f}", "valve_mlp.onnx",
                  "Baseline", "Model fit", "Timing", f"edc-bench {record.software_version}",
                  f"ICD {record.icd_version}", f"rig firmware {record.firmware_version}", "UTC"):
        assert shown in text, shown
    assert cls.model_sha256 in unbroken and pdf.parent.name in unbroken
    for name in ("af", "a1", "a0", "a2", "b", "a3"):
        assert f" {name} " in f" {text} ", name


def test_long_identities_are_wrapped_whole_on_page_1(report_of: Callable[[str], Path]) -> None:
    """Identities of 100 characters are set smaller and wrapped, never cut: the customer's paper names the part."""
    text = page_text(report_of("long values"), 1).replace(" ", "")
    for value in (LONG_VALVE_ID, *LONG_IDENTITY.values()):
        assert value.replace(" ", "") in text, value


def test_an_aborted_test_says_it_was_not_judged_and_why(report_of: Callable[[str], Path]) -> None:
    text = page_text(report_of("invalid"), 1)
    assert "INVALID" in text and "Not judged:" in text
    assert "this report says nothing about its condition" in text
    # in the customer's words, never the engineer's reason with its figures (#53: "more than 2 mm off for 100 ticks")
    from edc_bench.records.advice import CUSTOMER_WORDS

    flat = " ".join(text.split())
    assert "Why:" not in text and any(words in flat for words in CUSTOMER_WORDS.values()), flat


@pytest.mark.slow
def test_a_pump_whose_rack_binds_names_the_rack_on_both_pages(report_of: Callable[[str], Path]) -> None:
    """#67: page 1 tells the customer the pump's rack binds and the valve was not judged; page 2 gives the engineer
    the part, the finding with its figure against its limit, and what was within the limits."""
    pdf = report_of("rack")
    first, second = page_text(pdf, 1), page_text(pdf, 2)
    for shown in ("INVALID", "Not judged: the rack binds at one place: free or repair the rack",
                  "The pump's control rack binds at one place along its travel.",
                  "The pump's control rack or its rack-travel sensor is faulty"):
        assert shown in first, shown
    assert "replace the valve" not in first.lower()
    for shown in ("Part at fault rack: rack bind", "Which part is at fault", "Rack bind", "BEYOND", "Within limits"):
        assert shown in second, shown
    # a model that does not fit explains at length: the plots where they have their room, else where their data is
    assert "Estimates of af and a1 during the test" in second or "the record's trace.mf4 holds their data" in second
