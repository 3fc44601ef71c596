"""A test's PDF report as the web view serves it: drawn from a copy of the test's record, once the record is found
inside the records folder and is the one the history indexed.

A report file in a record folder is no evidence: it is drawn after the test, no digest covers it, and anyone who
may write the records folder may replace it. The record is covered: the history keeps the digest of its
record.json as first indexed, and record.json keeps the digests of the files beside it (the trace, the CAN log).
So the server copies the record's files once into a folder of its own, checks the copies (record.json against the
history, the rest against record.json's manifest, as every reader does) and draws the report from the copies, as
``edc-bench report`` would, with the test's history entry and chain hash in its footer: what is drawn is what was
checked, whatever happens in the records folder meanwhile. A MARGINAL's retest is shown only when the history
holds it and its record.json is the one indexed (a folder beside the record is no evidence either).
"""

from __future__ import annotations

import hashlib
import json
import tempfile
import threading
from collections import OrderedDict
from dataclasses import dataclass
from pathlib import Path

from edc_bench.errors import EdcBenchError
from edc_bench.records.writer import RECORD_FILE

#: The largest record file copied (a trace of a long test is a few MB; more is no record of this program's).
MAX_FILE_BYTES = 200 * 1024 * 1024


class ReportRefused(EdcBenchError):
    """The report is not served; the message says why, as a person reads it."""


class ReportBusy(EdcBenchError):
    """Another report is being drawn: one at a time, so that asking for reports cannot hold up every page."""


@dataclass(frozen=True)
class IndexedRecord:
    """A record folder found inside the records folder, and the digest the history kept of its record.json."""

    folder: Path
    record_sha256: str | None


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


def _read(path: Path) -> bytes:
    try:
        with open(path, "rb") as handle:
            data = handle.read(MAX_FILE_BYTES + 1)
    except OSError as exc:
        raise ReportRefused(f"{path.name} of this test's record cannot be read ({exc.strerror}): its report is "
                            "not drawn") from None
    if len(data) > MAX_FILE_BYTES:
        raise ReportRefused(f"{path.name} of this test's record is larger than any record's: its report is not drawn")
    return data


def _copy_checked(record: IndexedRecord, scratch: Path, record_json_only: bool = False) -> Path:
    """Copy ``record`` into ``scratch`` (a folder of the same name), record.json checked against the history's
    digest on the bytes copied; returns the copy. The other files are checked by the record's reader, on the
    copies."""
    if not record.record_sha256:
        raise ReportRefused("the history kept no digest of this test's record (it was indexed without one), so the "
                            "record cannot be checked: its report is not drawn")
    text = _read(record.folder / RECORD_FILE)
    if hashlib.sha256(text).hexdigest() != record.record_sha256:
        raise ReportRefused("this test's record.json in the records folder is not the one the history indexed "
                            "(changed or replaced since): its report is not drawn. 'edc-bench history --verify' "
                            "and 'edc-bench replay' on the folder say more")
    copy = scratch / record.folder.name
    copy.mkdir()
    (copy / RECORD_FILE).write_bytes(text)
    if record_json_only:
        return copy
    try:
        doc = json.loads(text)
    except ValueError:
        raise ReportRefused("this test's record.json is not JSON: its report is not drawn") from None
    files = doc.get("files") if isinstance(doc, dict) else None
    integrity = doc.get("integrity") if isinstance(doc, dict) else None
    manifest = integrity.get("files") if isinstance(integrity, dict) else None
    # the files record.json names (the trace, the CAN log) and those its manifest holds digests of
    names = {str(v) for k, v in (files.items() if isinstance(files, dict) else ())
             if isinstance(v, str) and not str(k).endswith("_error")}
    names |= {str(k) for k in (manifest if isinstance(manifest, dict) else ())}
    for name in sorted(names):
        source = record.folder / name
        if Path(name).name != name or name in (".", "..", RECORD_FILE) or not source.is_file() or source.is_symlink():
            continue  # a file of the record is a plain file beside record.json; the reader says what is missing
        (copy / name).write_bytes(_read(source))
    return copy


class ReportDrawer:
    """Draws reports from checked copies of records, one at a time, keeping the last few drawn (a record's report
    is asked again while a person reads a valve's story; drawing one takes about a second)."""

    def __init__(self, keep: int = 16) -> None:
        self._keep = keep
        self._drawn: OrderedDict[tuple[str, str, str], bytes] = OrderedDict()
        self._kept_lock = threading.Lock()
        self._one_at_a_time = threading.Lock()

    def pdf(self, test: IndexedRecord, history_note: str, retest: IndexedRecord | None = None) -> bytes:
        """The report of ``test`` as PDF bytes, ``history_note`` in its footer, ``retest`` (the history's retest
        of a MARGINAL) beside it when its record.json is the one indexed.

        Raises
        ------
        ReportRefused
            The history kept no digest of the record, the record is not the one indexed, or it changed since its
            test wrote it (its own manifest), or it cannot be read.
        ReportBusy
            Another report is being drawn.
        """
        key = (str(test.record_sha256), str(retest.record_sha256 if retest else ""), history_note)
        with self._kept_lock:
            if key in self._drawn:
                self._drawn.move_to_end(key)
                return self._drawn[key]
        if not self._one_at_a_time.acquire(blocking=False):
            raise ReportBusy("another report is being drawn: open this one again in a few seconds")
        try:
            with tempfile.TemporaryDirectory(prefix="edc-bench-report-") as scratch:
                copy = _copy_checked(test, Path(scratch))
                if retest is not None and retest.folder.name != test.folder.name:
                    try:
                        _copy_checked(retest, Path(scratch), record_json_only=True)
                    except ReportRefused:
                        pass  # a retest not as indexed is not shown: the report stands without it
                pdf = self._draw(copy, Path(scratch) / "drawn", history_note)
        finally:
            self._one_at_a_time.release()
        with self._kept_lock:
            self._drawn[key] = pdf
            while len(self._drawn) > self._keep:
                self._drawn.popitem(last=False)
        return pdf

    @staticmethod
    def _draw(copy: Path, out: Path, history_note: str) -> bytes:
        from edc_bench.records.report import draw_report
        from edc_bench.web.charts import drawing

        with drawing():
            try:
                pdf, _ = draw_report(copy, out, history_note, pngs=False)
            except EdcBenchError as exc:  # the record's own manifest: changed after its test wrote it
                shown = str(exc).replace(str(copy), copy.name)  # the server's folders are not the reader's business
                raise ReportRefused(f"{shown}; its report is not drawn") from None
            return pdf.read_bytes()


__all__ = ["IndexedRecord", "ReportBusy", "ReportDrawer", "ReportRefused", "record_folder"]
