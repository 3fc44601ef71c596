"""``history --verify``: every indexed record folder read again and held to what the history kept of it.

When a record is indexed the history keeps the SHA-256 of its record.json and the record's own integrity
manifest (records of schema 5 on: the digests of the trace, the CAN log and the figure). A test is held to its
*first* indexing, which stands: a folder is *missing* when it or its record.json is gone, *altered* when
record.json's bytes differ from those first indexed, or a file its manifest names changed; a test indexed again
with other content is *changed*, every time ``--verify`` runs (re-indexing a tampered record does not silence
it). Rows indexed before the history kept a hash can only be found missing. The hash chain
(:mod:`edc_bench.history.chain`) is checked beside this, by the store.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

from edc_bench.history.rows import AdoptionRow, TestRow
from edc_bench.records.integrity import Change, altered, file_digest
from edc_bench.records.writer import RECORD_FILE
from edc_bench.timefmt import local_text


@dataclass(frozen=True)
class RecordFinding:
    """One indexed test whose folder is not as it was indexed."""

    test_id: int
    valve_id: str
    record_dir: str
    problem: str  # 'missing', 'altered' or 'changed'
    detail: str


def check_row(row: TestRow) -> RecordFinding | None:
    """What is wrong with one indexed test's folder (None: as indexed, as far as the history can tell)."""
    folder = Path(row.record_dir)
    path = folder / RECORD_FILE

    def finding(problem: str, detail: str) -> RecordFinding:
        return RecordFinding(row.id, row.valve_id, row.record_dir, problem, detail)

    if not folder.is_dir():
        return finding("missing", "the record folder is gone")
    if not path.is_file():
        return finding("missing", f"{RECORD_FILE} is gone")
    changes: list[Change] = []
    if row.record_manifest:
        try:
            doc = json.loads(path.read_text(encoding="utf-8"))
        except (OSError, ValueError):
            doc = None
        # held to the manifest kept when it was indexed, not to the one in the folder now (which may be rewritten)
        manifest = json.loads(row.record_manifest)
        changes = altered({**doc, "integrity": manifest}, folder) if isinstance(doc, dict) else \
            [Change(f"{RECORD_FILE} (not readable)", RECORD_FILE)]
    if row.record_sha256 and file_digest(path) != row.record_sha256 \
            and not any(change.file == RECORD_FILE for change in changes):
        changes.insert(0, Change(f"{RECORD_FILE} (not the file indexed)", RECORD_FILE))
    return finding("altered", "; ".join(changes)) if changes else None


def verify(rows: list[TestRow]) -> list[RecordFinding]:
    """The findings over every indexed test as it stands (:meth:`~edc_bench.history.store.HistoryStore.indexed`).

    A folder that cannot be read (a file the system refuses, record.json damaged beyond reading) is a finding of
    its own: one bad folder never stops the check of the others.
    """
    found = []
    for row in rows:
        try:
            problem = check_row(row)
        except (OSError, ValueError, TypeError, AttributeError) as exc:
            problem = RecordFinding(row.id, row.valve_id, row.record_dir, "altered",
                                    f"not readable ({type(exc).__name__}: {exc})")
        if problem is not None:
            found.append(problem)
    return found


def changed_findings(rows: list[TestRow]) -> list[RecordFinding]:
    """One finding per row that indexed a test again with other content than its first indexing
    (:meth:`~edc_bench.history.store.HistoryStore.changed_tests`): the first stands, and this is said every time."""
    return [RecordFinding(int(row.first_id or 0), row.valve_id, row.record_dir, "changed",
                          f"indexed again with other content as row {row.id} ({row.verdict}, at "
                          f"{local_text(row.indexed_at, seconds=True)} by database login {row.db_login or '(none)'}): "
                          "the first indexing stands; the record was changed after its test")
            for row in rows]


def model_findings(rows: list[TestRow], adoptions: list[AdoptionRow], shipped: set[str]) -> list[RecordFinding]:
    """One finding per test judged by a model that is neither shipped nor adopted for its station in the history
    before it was indexed (an adoption that bypassed the chain, or a model put in the station's folder by hand).

    Parameters
    ----------
    rows : list of TestRow
        Tests as they stand (:meth:`~edc_bench.history.store.HistoryStore.indexed`).
    adoptions : list of AdoptionRow
        Every adoption the history holds.
    shipped : set of str
        The SHA-256 of the networks the bench judges with unless one is adopted.
    """
    found = []
    for row in rows:
        sha = row.model_sha256
        if not sha or sha in shipped:
            continue
        when = row.indexed_at or row.started_at or ""
        if any(a.station == row.station and a.model_sha256 == sha and a.adopted_at <= when for a in adoptions):
            continue
        found.append(RecordFinding(row.id, row.valve_id, row.record_dir, "model",
                                   f"judged by a model (sha256 {sha[:12]}..., {row.model_name or 'unnamed'}) the "
                                   f"history records no adoption of for station {row.station!r} before the test was "
                                   "indexed: an adoption that bypassed the history, or a model put in by hand"))
    return found
