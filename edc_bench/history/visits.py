"""A valve's visit: one test, or a MARGINAL and its retest, with the one decision the technician acted on.

The history keeps a row per test (machines read them: ``--json``, ``--csv``); people read visits. A retest's row
names its first test's record folder (``retest_of``) and the pair's ``decision``; its first test's row is the one
whose ``record_dir`` that is. Pure: rows in, visits out.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

from edc_bench.history.rows import TestRow


@dataclass(frozen=True)
class Visit:
    """One visit of a valve to the bench.

    Attributes
    ----------
    tests : tuple of TestRow
        Its tests' history rows, oldest first (two for a retested MARGINAL).
    """

    tests: tuple[TestRow, ...]

    @property
    def first(self) -> TestRow:
        """The visit's first test."""
        return self.tests[0]

    @property
    def last(self) -> TestRow:
        """The test that decided (a retest, else the only test)."""
        return self.tests[-1]

    @property
    def decision(self) -> str:
        """What the technician acted on: a retest pair's decision, else the test's verdict."""
        return str(self.last.decision or self.last.verdict)

    @property
    def verdicts(self) -> str:
        """Each test's verdict: ``MARGINAL then MARGINAL``."""
        return " then ".join(str(t.verdict) for t in self.tests)

    @property
    def ids(self) -> str:
        """The tests' history ids: ``12+13``."""
        return "+".join(str(t.id) for t in self.tests)


def visits(rows: Iterable[TestRow]) -> list[Visit]:
    """The visits of history rows (oldest first): a retest joins its first test when both are listed."""
    ordered = list(rows)
    by_folder = {str(r.record_dir): n for n, r in enumerate(ordered) if r.record_dir}
    first_of: dict[int, int] = {}  # retest's index -> its first test's index
    for n, row in enumerate(ordered):
        first = by_folder.get(str(row.retest_of)) if row.retest_of else None
        if first is not None and first < n and first not in first_of.values():
            first_of[n] = first
    joined = set(first_of.values())
    out = []
    for n, row in enumerate(ordered):
        if n in joined:
            continue  # shown with its retest
        out.append(Visit((ordered[first_of[n]], row) if n in first_of else (row,)))
    out.sort(key=lambda v: (str(v.first.started_at or ""), v.first.id or 0))
    return out


def with_visit_decisions(rows: list[TestRow]) -> list[dict[str, object]]:
    """The rows as JSON objects (a listing's columns), each with its visit's ``visit_decision`` and ``visit`` (its
    tests' ids): ``--json``."""
    seen: dict[int, Visit] = {}
    for visit in visits(rows):
        for test in visit.tests:
            seen[id(test)] = visit
    return [{**row.listed(), "visit_decision": seen[id(row)].decision, "visit": [t.id for t in seen[id(row)].tests]}
            for row in rows]


__all__ = ["Visit", "visits", "with_visit_decisions"]
