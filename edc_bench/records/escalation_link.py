"""A valve not judged twice: the earlier test of the same valve, found beside the new one, escalates the second.

A seized or very worn valve makes every test INVALID (the rack does not follow, the model does not fit it), and the
technician's line of each test alone, "check the mounting, then retest", loops. When a valve's test is INVALID
for a cause the valve itself can cause (:class:`~edc_bench.records.advice.Cause` ``VALVE``) and the same valve's
last test at this station, of the same pump type and within :data:`WINDOW_H` hours, was too, the second says the
valve may be seized (:func:`~edc_bench.records.advice.escalation`): on the screen, in ``edc-bench test``'s output,
in its record.json (``escalation``) and on both pages of its report.

Both front ends (``edc-bench test`` and the session) ask this one function, before the record is written, so the
record, the report and the screen say the same. The earlier test is found by its record folder (named by the
variant and the valve, :func:`~edc_bench.records.writer.new_record_dir`) and read from its record.json: the
history need not be reachable.
"""

from __future__ import annotations

import datetime as dt
import re
from pathlib import Path

from edc_bench.records.advice import Cause, escalation
from edc_bench.records.schema import EscalationSummary
from edc_bench.records.writer import RECORD_FILE
from edc_bench.verdict.verdicts import Verdict

#: how long after a valve's INVALID a second INVALID of it escalates (a valve tested again the next day is a new
#: visit: its own advice first)
WINDOW_H = 24.0


def _parse(started_at: str) -> dt.datetime | None:
    try:
        when = dt.datetime.fromisoformat(started_at)
    except (TypeError, ValueError):
        return None
    return when if when.tzinfo is not None else None


def _folder_time(name: str) -> dt.datetime | None:
    """The local start a record folder's name begins with (``20261126T110400+0100``), None if it has none."""
    try:
        return dt.datetime.strptime(name[:20], "%Y%m%dT%H%M%S%z")
    except ValueError:
        return None


def _written_ns(folder: Path) -> int:
    """When the folder's record.json was written (ns since the epoch; 0 if that cannot be read)."""
    try:
        return (folder / RECORD_FILE).stat().st_mtime_ns
    except OSError:
        return 0


def find_escalation(folder: Path, valve_id: str, variant: str, started_at: str, verdict: str,
                    cause: Cause | None) -> EscalationSummary | None:
    """The escalation of a test about to be written into ``folder``, or None.

    Parameters
    ----------
    folder : pathlib.Path
        The test's record folder (its siblings are the station's other records).
    valve_id, variant, started_at : str
        The test's valve, pump type and start (ISO 8601 with offset).
    verdict : str
        The test's verdict.
    cause : Cause or None
        Who the test points at if INVALID.

    Returns
    -------
    EscalationSummary or None
        The earlier record's folder and verdict and the technician's line, when both tests were INVALID for a
        cause the valve itself can cause; None otherwise (no valve id, no earlier test within the window, another
        cause either time).
    """
    from edc_bench.records.reader import load_record

    now = _parse(started_at)
    if verdict != Verdict.INVALID or cause is not Cause.VALVE or not valve_id or now is None:
        return None
    folder = Path(folder).resolve()
    safe_id = re.sub(r"[^\w.-]+", "_", valve_id).strip("_.") or "valve"
    marker = f"-{variant}-{safe_id}"
    try:
        candidates = [d for d in folder.parent.iterdir()
                      if d != folder and d.is_dir() and (d.name.endswith(marker) or f"{marker}-" in d.name)]
    except OSError:
        return None
    earlier: list[tuple[dt.datetime, int, Path, object]] = []
    for candidate in candidates:
        named = _folder_time(candidate.name)
        # a station's records folder may hold hundreds of one id's tests ("new"): only those its name puts near
        # the window are read (an hour's slack either side for a clock or zone change)
        if named is not None and not (dt.timedelta(hours=-1) <= now - named <= dt.timedelta(hours=WINDOW_H + 1)):
            continue
        try:
            record = load_record(candidate)
        except Exception:  # noqa: BLE001 - a damaged neighbour escalates nothing; its own reader says what it lacks
            continue
        when = _parse(record.started_at)
        if (record.valve_id == valve_id and record.variant == variant and when is not None
                and dt.timedelta(0) <= now - when <= dt.timedelta(hours=WINDOW_H)):
            # two tests may start within one second (started_at keeps seconds): the later written is the later
            written_ns = _written_ns(candidate)
            earlier.append((when, written_ns, candidate, record))
    if not earlier:
        return None
    _, _, last_folder, last = max(earlier, key=lambda entry: (entry[0], entry[1]))
    first_cause = last.invalid_cause if last.verdict == Verdict.INVALID else None  # type: ignore[attr-defined]
    advice = escalation(first_cause, cause)
    if advice is None:
        return None
    return EscalationSummary(of_record=last_folder.name, of_verdict=str(last.verdict),  # type: ignore[attr-defined]
                             of_cause=str(first_cause), words=advice.words)


def recorded_escalation(record_dir: Path | None) -> EscalationSummary | None:
    """The escalation a written record holds (None: none, no folder, or a record that does not read back, which its
    own reader reports)."""
    from edc_bench.records.reader import load_record

    if record_dir is None:
        return None
    try:
        return load_record(record_dir).escalation
    except Exception:  # noqa: BLE001 - never worth more than the verdict already shown
        return None


__all__ = ["WINDOW_H", "find_escalation", "recorded_escalation"]
