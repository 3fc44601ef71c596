"""Where the history is: its URL, checked before any work, and the station's default.

A SQLite file URL (the station's default, and what a shop mostly gives) is
checked without importing SQLAlchemy, so ``edc-bench test`` refuses a bad
history before the test without paying that import before its first tick;
any other URL is parsed by SQLAlchemy.
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from edc_bench.errors import ConfigError
from edc_bench.history.secrets import raw_at_in_password, shown_url


def default_url() -> str:
    """``EDC_BENCH_HISTORY_URL`` if set, else SQLite in the station's data folder."""
    configured = os.environ.get("EDC_BENCH_HISTORY_URL")
    if configured:
        return configured
    from edc_bench.paths import data_dir

    return f"sqlite:///{data_dir() / 'history.sqlite'}"


@contextmanager
def scratch_history() -> Iterator[str]:
    """For runs that are no shop's tests (the benchmark's): the history URL pointed at a throw-away SQLite file for
    the ``with`` block, in this process and every process it starts, so that nothing they run reaches the
    station's history (nor a shop's PostgreSQL named by ``EDC_BENCH_HISTORY_URL``). Yields the URL."""
    saved = os.environ.get("EDC_BENCH_HISTORY_URL")
    with tempfile.TemporaryDirectory(prefix="edc-bench-scratch-") as folder:
        url = f"sqlite:///{Path(folder) / 'history.sqlite'}"
        os.environ["EDC_BENCH_HISTORY_URL"] = url
        try:
            yield url
        finally:
            if saved is None:
                os.environ.pop("EDC_BENCH_HISTORY_URL", None)
            else:
                os.environ["EDC_BENCH_HISTORY_URL"] = saved


#: The first bytes of every SQLite database file.
SQLITE_HEADER = b"SQLite format 3\x00"


def check_url(url: str | None, must_exist: bool = False) -> None:
    """Check a history URL without connecting: its form, its driver, and for SQLite the file and its folder.

    The default (the station's data folder) is made if missing; a folder
    named in a URL is never made, so a mistyped URL cannot start a second,
    empty history beside the shop's.

    Parameters
    ----------
    url : str, optional
        ``--db``; default :func:`default_url` (``EDC_BENCH_HISTORY_URL``, else the data folder's SQLite file).
    must_exist : bool, optional
        For commands that only read or label what is there: a SQLite file named by ``--db`` or
        ``EDC_BENCH_HISTORY_URL`` must exist (a mistyped name would show an empty history, or keep a
        finding where no one looks for it).

    Raises
    ------
    ConfigError
        Naming the URL, where it came from, what is wrong and what to give instead.
    """
    given = url or os.environ.get("EDC_BENCH_HISTORY_URL")
    text = url or default_url()
    where = "" if url or not given else " (from EDC_BENCH_HISTORY_URL)"
    fix = "give another with --db URL" + (" or EDC_BENCH_HISTORY_URL" if where else "")
    path = plain_sqlite_path(text)
    if path is None:
        path = _parsed_sqlite_path(text, where)
        if path is None:
            return  # another database: its server says the rest when connected
    _check_sqlite_file(path, f"history database {shown_url(text)}{where}", fix, default=not given)
    if must_exist and given and not path.exists():
        raise ConfigError(f"history database {shown_url(text)}{where}: there is no history at {path}; check the URL "
                          "(nothing was created). A new history is started by 'edc-bench test' or "
                          "'edc-bench history --add' with this URL")


#: Characters that make SQLAlchemy read a URL as more than a file path (escapes, options, fragments).
_URL_SPECIAL = frozenset("%?#")


def plain_sqlite_path(text: str) -> Path | None:
    """The file of ``sqlite:///FILE`` when FILE holds nothing SQLAlchemy would decode; None otherwise.

    The file SQLAlchemy would open (``make_url(text).database``), read
    without importing SQLAlchemy: checking the station's history before a
    test must not cost the test's start its import. Any other URL is for
    SQLAlchemy to parse.
    """
    prefix = "sqlite:///"
    if not text.startswith(prefix) or _URL_SPECIAL & set(text):
        return None
    database = text[len(prefix):]
    return Path(database) if database and database != ":memory:" else None


def _parsed_sqlite_path(text: str, where: str) -> Path | None:
    """The SQLite file a URL names, checked by SQLAlchemy (None: not SQLite); a ConfigError if it is no use."""
    import sqlalchemy as sa

    if raw_at_in_password(text):  # SQLAlchemy would take what follows the '@' for the host, and show it
        raise ConfigError(f"history database {shown_url(text)!r}{where}: its password holds a raw '@', which ends "
                          "a password in a URL: write each '@' in it as %40 (p@ss as p%40ss)")
    try:
        parsed = sa.engine.make_url(text)
    except sa.exc.ArgumentError:
        hint = f" (a file: sqlite:///{text})" if "://" not in text else ""
        raise ConfigError(f"history database {shown_url(text)!r}{where} is not a database URL: use sqlite:///FILE{hint} or "
                          "postgresql+psycopg://USER@HOST/DB") from None
    except ValueError:  # SQLAlchemy's int() of what it read as the port
        raise ConfigError(f"history database {shown_url(text)!r}{where}: its port is not a number; give "
                          "HOST:PORT with digits (postgresql+psycopg://USER@HOST:5432/DB), or HOST alone") from None
    shown = shown_url(parsed.render_as_string(hide_password=True))  # SQLAlchemy shows a ?password= as it is
    if parsed.get_backend_name() not in ("sqlite", "postgresql"):
        raise ConfigError(f"history database {shown!r}{where}: {parsed.get_backend_name()!r} is not a database "
                          "edc-bench keeps its history in; use SQLite (sqlite:///FILE) or PostgreSQL "
                          "(postgresql+psycopg://USER@HOST/DB)") from None
    try:
        parsed.get_dialect()
    except (sa.exc.NoSuchModuleError, ImportError) as exc:
        raise ConfigError(f"history database {shown!r}{where}: its driver is not installed ({exc}); for "
                          "PostgreSQL install edc-bench[postgres] (psycopg), or use sqlite:///FILE") from None
    if parsed.get_backend_name() != "sqlite":
        return None
    if parsed.database in (None, "", ":memory:"):
        raise ConfigError(f"history database {shown_url(text)!r}{where} is in memory and keeps nothing: give a file, "
                          "sqlite:///FILE")
    if parsed.query:
        raise ConfigError(f"history database {shown_url(text)!r}{where}: options after '?' are not used; give the file "
                          "alone, sqlite:///FILE")
    return Path(parsed.database)


def damaged_advice(path: Path | str) -> str:
    """What a technician does about a damaged history file: test on without it, or rebuild it from the records
    (which stay the source of truth)."""
    return (f"to test on, give --no-history (each record stays on disk); to rebuild the history, move the file aside "
            f"(mv {path} {path}.damaged) and index the records again: edc-bench history --add RECORDS_FOLDER/*")


def _check_sqlite_file(path: Path, what: str, fix: str, default: bool) -> None:
    """Refuse a SQLite target that is a folder, a device, another kind of file, or in a missing folder."""
    if path.is_dir():
        raise ConfigError(f"{what}: {path} is a folder; name a file in it, e.g. sqlite:///{path / 'history.sqlite'}")
    if path.exists() and not path.is_file():
        raise ConfigError(f"{what}: {path} is a device or other special file, not a database file; {fix}")
    if path.is_file() and path.stat().st_size > 0:
        try:
            with path.open("rb") as handle:
                header = handle.read(len(SQLITE_HEADER))
        except OSError as exc:
            raise ConfigError(f"{what}: cannot read {path} ({exc.strerror}); {fix}") from None
        if header != SQLITE_HEADER:
            raise ConfigError(f"{what}: {path} is not a SQLite database (it holds other data, or is damaged); "
                              f"refusing to touch it: {fix}; {damaged_advice(path)}")
    if not path.parent.is_dir():
        if default:
            path.parent.mkdir(parents=True, exist_ok=True)  # the station's own data folder, on a fresh station
        else:
            raise ConfigError(f"{what}: the folder {path.parent} does not exist; make it first (mkdir -p "
                              f"{path.parent}) or {fix}")
