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
#: Where PostgreSQL says an error came from when a PL/pgSQL ``RAISE`` made it (its diagnostics' source function):
#: only the history's own triggers raise, so their refusal is shown in their own words.
PLPGSQL_RAISE = "exec_stmt_raise"
#: SQLite's codes: a trigger's ``RAISE(ABORT, ...)`` (only the history's own triggers raise), a damaged file.
SQLITE_CONSTRAINT_TRIGGER = 1811
SQLITE_DAMAGED = frozenset({11, 26})  # SQLITE_CORRUPT, SQLITE_NOTADB (primary codes: the low byte of the extended)
#: How the history's own triggers begin a refusal (0006's; the append-only ones say 'edc-bench history is ...').
_OWN_PREFIX = "edc-bench history:"


def raised_by_history(orig: BaseException) -> bool:
    """Whether the driver's error is one of the history's own triggers refusing a change (by the error's codes,
    not its words: a trigger's text may change, a login's message may hold anything)."""
    diag = getattr(orig, "diag", None)
    if diag is not None and getattr(diag, "source_function", None) == PLPGSQL_RAISE:
        return True
    return getattr(orig, "sqlite_errorcode", None) == SQLITE_CONSTRAINT_TRIGGER


def problem(exc: sa.exc.DBAPIError, action: str, shown_url: str, login: str | None = None) -> str:
    """One line for ``exc`` met while doing ``action`` (a key of :data:`~edc_bench.history.roles.RIGHTS`)."""
    orig = exc.orig
    text = str(orig).strip()
    first = text.splitlines()[0] if text else type(orig).__name__
    if raised_by_history(orig):  # the database's own words (the history's triggers)
        return first.removeprefix(_OWN_PREFIX).strip()
    if getattr(orig, "sqlstate", None) == INSUFFICIENT_PRIVILEGE:
        return refusal(action, login)
    if ((getattr(orig, "sqlite_errorcode", None) or 0) & 0xFF) in SQLITE_DAMAGED:  # a station's file, damaged
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
