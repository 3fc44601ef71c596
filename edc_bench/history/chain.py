"""The history's hash chain: every row carries the hash of its chain's previous row, so a row edited, deleted or
inserted between two others breaks the chain where it was done.

A *chain* is the rows of one table that one station (or, for findings and withdrawals, one database login) wrote,
in the order written (their ids). Each row keeps ``prev_hash``, the ``row_hash`` of the chain's row before it, and
``row_hash``, the SHA-256 of ``prev_hash | table | the row's content``, the content being the row as canonical JSON
(keys sorted, empty values left out, so that a column a later revision adds leaves older hashes as they are).

Rows written before the history had a chain (schema revision 0006) carry no hash: the revision anchored them
instead, one ``chain_anchors`` row per chain with the digest of all of them, which the first chained row takes as
its ``prev_hash``.

On PostgreSQL the database computes both hashes itself (a trigger, revision 0006), so no
station's program can write a row that claims another row's place; ``--verify`` recomputes them there too. On a
station's SQLite file the program computes them (this module), and the file's append-only triggers refuse a row
without one; what SQLite cannot stop (someone who rewrites the whole file with the program's own code) is caught
only against a hash kept outside the station: a chain head written down (``history --heads``), or the chain hash
printed on a customer's report.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Any

#: The tables that are chained, and the column that names a row's chain ('' where the row has none).
CHAIN_COLUMN = {"tests": "station", "teardowns": "db_login", "amendments": "db_login", "adoptions": "station",
                "reference_valves": "station", "rig_checks": "station", "guard_events": "db_login"}

#: The columns no row's content hash includes (they are the chain itself).
CHAIN_FIELDS = ("prev_hash", "row_hash")


def chain_of(table: str, row: Mapping[str, Any]) -> str:
    """The chain a row of ``table`` belongs to (its station, or its database login; '' for none)."""
    return str(row.get(CHAIN_COLUMN[table]) or "")


def canonical(row: Mapping[str, Any]) -> str:
    """A row's content as the chain hashes it: JSON, keys sorted, no empty values, no chain fields."""
    content = {key: value for key, value in row.items() if value is not None and key not in CHAIN_FIELDS}
    return json.dumps(content, sort_keys=True, separators=(",", ":"), ensure_ascii=False, allow_nan=True)


def row_hash(table: str, prev_hash: str, row: Mapping[str, Any]) -> str:
    """The ``row_hash`` of a row of ``table`` that follows ``prev_hash`` in its chain."""
    return hashlib.sha256(f"{prev_hash}|{table}|{canonical(row)}".encode()).hexdigest()


def anchor_hash(rows: Iterable[Mapping[str, Any]]) -> str:
    """The digest of a chain's rows written before the chain (in id order): what its first chained row follows."""
    text = "\n".join(canonical(row) for row in rows)
    return hashlib.sha256(text.encode()).hexdigest()


def legacy_test_key(started_at: str, valve_id: str, pump_serial: str, station: str, retest_of: str = "") -> str:
    """The key of a test whose record carries no id of its own (records before schema 8): what the record says of
    when, which valve, which pump and where. Revision 0006 gives the rows indexed before it the same key.

    ``retest_of`` (a retest's first test's folder) tells a MARGINAL's retest from its first test when both started
    in the same second (a simulated test takes less than one): without it the retest was taken for the first test
    indexed again, and its row never listed (the session's soak: 298 rows for 300 tests).
    """
    text = f"{started_at}|{valve_id}|{pump_serial}|{station}" + (f"|retest of {retest_of}" if retest_of else "")
    return "legacy:" + hashlib.sha256(text.encode()).hexdigest()


@dataclass(frozen=True)
class Break:
    """One place where a chain does not hold."""

    table: str
    chain: str
    row_id: int | None
    detail: str

    def line(self) -> str:
        """The break as one line: where, and what."""
        where = f"row {self.row_id} of {self.table}" if self.row_id is not None else f"table {self.table}"
        return f"{where} (chain {self.chain or '(none)'}): {self.detail}"


def check_chain(table: str, rows: Iterable[Mapping[str, Any]], anchors: Mapping[str, Mapping[str, Any]],
                recomputed: Mapping[int, str] | None = None,
                legacy_digests: Mapping[str, str] | None = None,
                verified_heads: Mapping[str, str] | None = None) -> list[Break]:
    """Where the chains of ``table`` break.

    Parameters
    ----------
    table : str
        The table the rows are from.
    rows : iterable of mapping
        Every row of the table, in id order, with ``prev_hash`` and ``row_hash``.
    anchors : mapping
        Each chain's anchor (``chain_anchors``' newest row of this table and chain): ``hash``, ``rows``,
        ``last_id``.
    recomputed : mapping, optional
        Each row's hash as the database recomputed it (PostgreSQL, id to hash); computed here otherwise.
    legacy_digests : mapping, optional
        Each anchored chain's digest of its unhashed rows as the database recomputed it (PostgreSQL); computed here
        otherwise.
    verified_heads : mapping, optional
        Each chain's last hash as checked before, when ``rows`` are only the rows added since (a check goes on
        from there; the anchors, of rows older than any such check, are left to the full one).

    Returns
    -------
    list of Break
        Rows whose content no longer gives their hash (edited), rows that do not follow their chain's previous row
        (a row deleted or inserted before them), rows with no hash written after the chain began (triggers
        switched off), and anchors whose rows are no longer those anchored.
    """
    breaks: list[Break] = []
    legacy: dict[str, list[Mapping[str, Any]]] = {}
    last: dict[str, str] = dict(verified_heads or {})
    for row in rows:
        chain = chain_of(table, row)
        if row.get("row_hash") is None:
            anchor = anchors.get(chain)
            if anchor is None or row["id"] > anchor["last_id"] or chain in last:
                breaks.append(Break(table, chain, row["id"], "a row without its chain hash, written after the chain "
                                                             "began (the database's triggers were off)"))
            else:
                legacy.setdefault(chain, []).append(row)
            continue
        if chain not in last:
            anchor = anchors.get(chain)
            last[chain] = str(anchor["hash"]) if anchor is not None else ""
        expected = recomputed[row["id"]] if recomputed is not None else row_hash(table, str(row["prev_hash"] or ""),
                                                                                  row)
        if row["prev_hash"] != last[chain]:
            breaks.append(Break(table, chain, row["id"], "does not follow the chain's row before it (a row was "
                                                         "deleted or put in before it)"))
        if expected != row["row_hash"]:
            breaks.append(Break(table, chain, row["id"], "its content no longer gives its hash (the row was edited)"))
        last[chain] = str(row["row_hash"])
    for chain, anchor in anchors.items() if verified_heads is None else ():
        kept = legacy.get(chain, [])
        digest = legacy_digests.get(chain, "") if legacy_digests is not None else anchor_hash(kept)
        if len(kept) != anchor["rows"] or digest != anchor["hash"]:
            breaks.append(Break(table, chain, None, f"the {anchor['rows']} row(s) written before the chain began are "
                                                    f"not as anchored ({len(kept)} there now; edited or deleted)"))
    return breaks


__all__ = ["CHAIN_COLUMN", "Break", "anchor_hash", "canonical", "chain_of", "check_chain", "legacy_test_key",
           "row_hash"]
