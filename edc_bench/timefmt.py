"""Times as people read them: local, with the offset from UTC; machines keep UTC.

record.json, the history's rows and CSV exports keep UTC (ISO 8601 with the
zone). Everything a person reads (screens, reports, listings, the rig
ledger, the shift summary, record folders a person browses) shows the
station's local time with its offset, so "11:04 +01:00" in Berlin and
"10:04 +00:00" in Lisbon are one moment, and a listing across a change to
summer time is unambiguous. A stored time without an offset is UTC: the
history writes its own stamps so (PostgreSQL's ``clock_timestamp() AT TIME
ZONE 'UTC'``).
"""

from __future__ import annotations

import datetime as dt

__all__ = ["folder_stamp", "local_column", "local_text", "offset_text", "parse_local_input", "parse_stored",
           "utc_bound", "utc_now_iso"]


def parse_stored(value: str | dt.datetime | None) -> dt.datetime | None:
    """A stored time as an aware datetime (no offset: UTC); None if empty, a date alone, or not a time."""
    if value is None or value == "":
        return None
    if isinstance(value, dt.datetime):
        when = value
    else:
        text = str(value).strip()
        if len(text) <= 10:  # a date alone has no time of day to move to another zone
            return None
        try:
            when = dt.datetime.fromisoformat(text)
        except ValueError:
            return None
    return when if when.tzinfo is not None else when.replace(tzinfo=dt.UTC)


def offset_text(when: dt.datetime) -> str:
    """``+01:00``: the offset of an aware datetime from UTC."""
    offset = when.utcoffset()
    minutes = round(offset.total_seconds() / 60) if offset is not None else 0
    sign = "-" if minutes < 0 else "+"
    return f"{sign}{abs(minutes) // 60:02d}:{abs(minutes) % 60:02d}"


def local_text(value: str | dt.datetime | None, *, seconds: bool = False, empty: str = "") -> str:
    """``2026-11-26 11:04 +01:00``: a stored time in this station's zone with its offset.

    Parameters
    ----------
    value : str or datetime or None
        ISO 8601 as stored (without an offset: UTC), or a datetime.
    seconds : bool
        To the second instead of the minute.
    empty : str
        What an empty value reads as.

    A date alone, or text that is no time, is given as it is.
    """
    when = parse_stored(value)
    if when is None:
        return empty if value is None or value == "" else str(value)
    local = when.astimezone()
    shown = f"{local:%Y-%m-%d %H:%M:%S}" if seconds else f"{local:%Y-%m-%d %H:%M}"
    return f"{shown} {offset_text(local)}"


def local_column(values: list[str | dt.datetime | None], *, seconds: bool = False) -> tuple[list[str], str]:
    """A table's time column in local time, and the note its title carries.

    When every time has the same offset the cells leave it out and the note says it once ("local time,
    UTC+01:00"); across a change to or from summer time each cell carries its own ("local time").
    """
    local = [when.astimezone() if (when := parse_stored(v)) is not None else None for v in values]
    offsets = {offset_text(w) for w in local if w is not None}
    if len(offsets) > 1:
        return [local_text(v, seconds=seconds) for v in values], "local time"
    form = "%Y-%m-%d %H:%M:%S" if seconds else "%Y-%m-%d %H:%M"
    cells = [f"{w:{form}}" if w is not None else local_text(v) for v, w in zip(values, local, strict=True)]
    zone = f", UTC{next(iter(offsets))}" if offsets else ""
    return cells, f"local time{zone}"


def folder_stamp(value: str | dt.datetime) -> str:
    """``20261126T110400+0100``: a record folder's time, local with its offset (a person browses the folders);
    a time that does not parse gives its digits, as before."""
    when = parse_stored(value)
    if when is None:
        return "".join(c for c in str(value).split("+")[0] if c.isdigit() or c == "T")
    local = when.astimezone()
    return f"{local:%Y%m%dT%H%M%S}{offset_text(local).replace(':', '')}"


def parse_local_input(text: str) -> dt.datetime:
    """A time a person typed (ISO 8601): local time unless it gives an offset; aware. Raises ValueError."""
    when = dt.datetime.fromisoformat(text.strip())
    return when.astimezone() if when.tzinfo is None else when


def utc_bound(text: str, *, end_of_day: bool = False) -> str:
    """A day or time a person typed, local unless it gives an offset, as the UTC instant the history's stamps are
    compared with (ISO 8601, to the second): a day's first second, or with ``end_of_day`` its last. Raises
    ValueError."""
    if "T" in text:
        return parse_local_input(text).astimezone(dt.UTC).isoformat(timespec="seconds")
    day = dt.date.fromisoformat(text)
    start = dt.datetime.combine(day + dt.timedelta(days=1) if end_of_day else day, dt.time()).astimezone()
    moment = start - dt.timedelta(seconds=1) if end_of_day else start
    return moment.astimezone(dt.UTC).isoformat(timespec="seconds")


def utc_now_iso() -> str:
    """Now, in UTC to the second, as records and the history store it."""
    return dt.datetime.now(dt.UTC).isoformat(timespec="seconds")
