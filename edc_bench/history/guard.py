"""A database's errors as one line a person can act on, never a driver's traceback, never a password."""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from contextlib import contextmanager

import sqlalchemy as sa

from edc_bench.errors import ConfigError
from edc_bench.history.roles import refusal
from edc_bench.history.secrets import redact

#: PostgreSQL's SQLSTATE for a privilege the login lacks.
INSUFFICIENT_PRIVILEGE = "42501"
#: What SQLite says of a damaged file.
_DAMAGED = ("malformed", "not a database", "disk image", "file is encrypted")


def problem(exc: sa.exc.DBAPIError, action: str, shown_url: str, login: str | None = None) -> str:
    """One line for ``exc`` met while doing ``action`` (a key of :data:`~edc_bench.history.roles.RIGHTS`)."""
    orig = exc.orig
    text = str(orig).strip()
    first = text.splitlines()[0] if text else type(orig).__name__
    if first.startswith("edc-bench history:"):  # the database's own words (revision 0006's triggers)
        return first.removeprefix("edc-bench history:").strip()
    if getattr(orig, "sqlstate", None) == INSUFFICIENT_PRIVILEGE:
        return refusal(action, login)
    if "append-only" in first:  # the history's own triggers
        return first
    if shown_url.startswith("sqlite") and any(words in first for words in _DAMAGED):  # a station's file, damaged
        from edc_bench.history.url import damaged_advice

        path = shown_url.removeprefix("sqlite:///")
        return f"history database {shown_url} is damaged ({first}): {damaged_advice(path)}"
    if isinstance(exc, sa.exc.OperationalError):  # the server down, the file locked...
        return f"history database {shown_url}: {first}"
    return f"history database {shown_url}: {type(orig).__name__}: {first}"


@contextmanager
def database_errors(action: str, shown_url: str, secrets: Iterable[str] = (), login: str | None = None) -> Iterator[None]:
    """Turn a database error inside the block into a :class:`ConfigError` (:func:`problem`), password removed."""
    try:
        yield
    except sa.exc.DBAPIError as exc:
        raise ConfigError(redact(problem(exc, action, shown_url, login), secrets)) from None
