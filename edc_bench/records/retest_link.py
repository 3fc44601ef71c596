"""A MARGINAL's retest, found beside its record: the first test's report names the pair's decision too.

The first test's record.json is written before its retest runs, so it cannot name it; the retest's names the first
(``retest.of_record``). The two folders sit side by side, the retest's named like the first's at a later time
(:func:`~edc_bench.records.writer.new_record_dir`): only the nearest folders of the same pump type and valve are
read.
"""

from __future__ import annotations

import json
from pathlib import Path

from edc_bench.records.schema import Record, RetestedBy
from edc_bench.records.writer import RECORD_FILE
from edc_bench.verdict.verdicts import Verdict

#: later folders of the same valve read at most (a retest follows its first test at once)
_LOOKED_AT = 8


def _valve_part(name: str, variant: str) -> str | None:
    """The ``<variant>-<valve>`` part of a record folder's name (without a ``-2`` of a second folder that second)."""
    marker = f"-{variant}-"
    at = name.find(marker)
    return None if at < 0 else name[at + 1:]


def find_retest(folder: Path, record: Record) -> RetestedBy | None:
    """The retest of the record in ``folder``, if one beside it names it (None for a test that was not a MARGINAL
    retested, or whose retest is not beside it)."""
    folder = Path(folder).resolve()  # "." names no folder
    if record.retest is not None or str(record.verdict) != "MARGINAL" or not record.variant:
        return None
    own = _valve_part(folder.name, record.variant)
    if own is None:
        return None
    base = own.rsplit("-", 1)[0] if own.rsplit("-", 1)[-1].isdigit() else own
    try:
        same_valve = sorted(d for d in folder.parent.iterdir()
                            if (_valve_part(d.name, record.variant) or "").startswith(base))
    except OSError:
        return None
    # the nearest by name, after it first: a retest follows its test at once, but folders are named in local time,
    # so across a change of summer time (or of zone) a later test may sort before it
    at = same_valve.index(folder) if folder in same_valve else len(same_valve)
    nearest = sorted((d for d in same_valve if d != folder),
                     key=lambda d: (abs(same_valve.index(d) - at), same_valve.index(d) < at))
    for candidate in nearest[:_LOOKED_AT]:
        try:
            doc = json.loads((candidate / RECORD_FILE).read_text(encoding="utf-8"))
        except (OSError, ValueError):
            continue
        retest = doc.get("retest") if isinstance(doc, dict) else None
        if isinstance(retest, dict) and retest.get("of_record") == folder.name:
            # the neighbour's words, as far as they are a verdict: its damaged record does not stop this report
            return RetestedBy(record=candidate.name, verdict=_verdict(doc.get("verdict")),
                              decision=_verdict(retest.get("decision")), words=str(retest.get("words", "")))
    return None


def _verdict(value: object) -> Verdict | None:
    """``value`` as a verdict, or None where it is none (missing, damaged)."""
    try:
        return Verdict(value)
    except ValueError:
        return None


__all__ = ["find_retest"]
