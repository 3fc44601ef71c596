"""A test's PDF report as the web view serves it: drawn from the test's record, once the record is found inside
the records folder and is the one the history indexed.

A report file in a record folder is no evidence: it is drawn after the test, no digest covers it, and anyone who
may write the records folder may replace it. The record is covered: the history keeps the digest of its
record.json as first indexed, and record.json keeps the digests of the files beside it (the trace, the CAN log).
So the server draws the report itself from a record that passes both checks, as ``edc-bench report`` would, with
the test's history entry and chain hash in its footer, and refuses, saying why, a record that does not.
"""

from __future__ import annotations

import tempfile
import threading
from collections import OrderedDict
from pathlib import Path

from edc_bench.errors import EdcBenchError
from edc_bench.records.integrity import file_digest
from edc_bench.records.writer import RECORD_FILE


class ReportRefused(EdcBenchError):
    """The report is not served; the message says why, as a person reads it."""


def record_folder(records_dir: Path | None, record_dir: str) -> Path | None:
    """The record folder a history row names, if its record.json is a file inside ``records_dir``: the folder as
    the row names it, else a folder of the same name directly in ``records_dir`` (a chain's server keeps the
    stations' record folders under one folder, where the names the stations indexed them by do not lead). A row's
    folder is what a station wrote: never followed outside the records (links resolved first)."""
    if records_dir is None:
        return None
    root = records_dir.resolve()
    named = Path(record_dir)
    for folder in (named, root / named.name):
        try:
            record = (folder / RECORD_FILE).resolve()
        except (OSError, RuntimeError, ValueError):
            continue
        if record.is_relative_to(root) and record.is_file():
            return record.parent
    return None


def _check_indexed(folder: Path, indexed_sha256: str | None) -> None:
    if not indexed_sha256:
        raise ReportRefused("the history kept no digest of this test's record (it was indexed without one), so the "
                            "record cannot be checked: its report is not drawn")
    try:
        found = file_digest(folder / RECORD_FILE)
    except OSError as exc:
        raise ReportRefused(f"this test's record cannot be read ({exc.strerror}): its report is not drawn") from None
    if found != indexed_sha256:
        raise ReportRefused("this test's record.json in the records folder is not the one the history indexed "
                            "(changed or replaced since): its report is not drawn. 'edc-bench history --verify' "
                            "and 'edc-bench replay' on the folder say more")


class ReportDrawer:
    """Draws reports from checked records, keeping the last few drawn (a record's report is asked again and again
    while a person reads a valve's story; drawing one takes about a second)."""

    def __init__(self, keep: int = 8) -> None:
        self._keep = keep
        self._drawn: OrderedDict[tuple[str, str], bytes] = OrderedDict()
        self._lock = threading.Lock()

    def pdf(self, folder: Path, indexed_sha256: str | None, history_note: str) -> bytes:
        """The report of the record in ``folder`` as PDF bytes, ``history_note`` in its footer.

        Raises
        ------
        ReportRefused
            The history kept no digest of the record, the record is not the one indexed, or it changed since its
            test wrote it (its own manifest), or it cannot be read.
        """
        _check_indexed(folder, indexed_sha256)
        key = (str(indexed_sha256), history_note)
        with self._lock:
            if key in self._drawn:
                self._drawn.move_to_end(key)
                return self._drawn[key]
        pdf = self._draw(folder, history_note)
        _check_indexed(folder, indexed_sha256)  # still the same record: not swapped while it was drawn
        with self._lock:
            self._drawn[key] = pdf
            while len(self._drawn) > self._keep:
                self._drawn.popitem(last=False)
        return pdf

    @staticmethod
    def _draw(folder: Path, history_note: str) -> bytes:
        from edc_bench.records.report import draw_report
        from edc_bench.web.charts import drawing

        with tempfile.TemporaryDirectory(prefix="edc-bench-report-") as scratch, drawing():
            try:
                pdf, _ = draw_report(folder, Path(scratch), history_note, pngs=False)
            except EdcBenchError as exc:  # the record's own manifest: changed after its test wrote it
                raise ReportRefused(f"{exc}; its report is not drawn") from None
            return pdf.read_bytes()


__all__ = ["ReportDrawer", "ReportRefused", "record_folder"]
