"""What the history holds of one record: where it stands in the chain, and whether the record is still the one
first indexed. ``report`` prints the chain's hash of the test on the customer's page (an anchor outside the
station: the customer keeps it), and ``report`` and ``classify`` refuse a record that is not what the history
first indexed for its test."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from edc_bench.errors import EdcBenchError
from edc_bench.records.integrity import file_digest
from edc_bench.records.writer import RECORD_FILE
from edc_bench.timefmt import local_text

if TYPE_CHECKING:
    from edc_bench.records.schema import Record


@dataclass(frozen=True)
class Standing:
    """One test as the history holds it: its row, where it was indexed, its chain hash, and what differs."""

    row_id: int
    station: str
    indexed_at: str
    row_hash: str | None
    changes: int
    #: one line when the record in the folder is not the record first indexed (None: the same, or not known)
    differs: str | None

    def note(self) -> str:
        """The line a report prints: the history's test and its chain hash (what a kept head is checked against)."""
        chain = f", chain {self.row_hash[:16]}" if self.row_hash else ""
        return f"history test {self.row_id}{chain}"


def history_standing(record: Record, folder: Path, url: str | None = None) -> Standing | None:
    """The test of ``record`` (in ``folder``) as the history at ``url`` (default: the station's) holds it.

    None when there is no history to ask (the station's file not made yet, a server that cannot be reached) or it
    does not hold the test: a report is drawn and a record classified without it.
    """
    from edc_bench.history.store import HistoryStore, test_key
    from edc_bench.history.url import default_url, plain_sqlite_path

    text = url or default_url()
    path = plain_sqlite_path(text)
    if path is not None and not path.is_file():
        return None  # never made: a station that keeps no history, nothing to open (nor to create)
    try:
        with HistoryStore(text, must_exist=True) as store:
            row = store.first_indexing(test_key(record))
    except EdcBenchError:
        return None
    if row is None:
        return None
    differs = None
    record_file = Path(folder) / RECORD_FILE
    if row.record_sha256 and record_file.is_file() and file_digest(record_file) != row.record_sha256:
        differs = (f"record.json is not the record the history first indexed for this test (history test "
                   f"{row.id}, indexed {local_text(row.indexed_at)} at station "
                   f"{row.station}, {row.verdict}): it was changed after it was indexed")
    return Standing(int(row.id), str(row.station), str(row.indexed_at or ""), row.row_hash, int(row.changes or 0),
                    differs)


__all__ = ["Standing", "history_standing"]
