"""The history's schema revisions: where a database stands, what an upgrade would do, and doing it.

The revisions are Alembic's (SQLAlchemy's migration tool), kept in ``migrations/versions/``, one file per change
with what it does in its docstring. A station's SQLite file is brought up to date when it is opened; a shop's
PostgreSQL is upgraded by its owner, who sees each change first (``edc-bench history --schema``, then
``--upgrade``): stations refuse a database that is not at this edc-bench's revision, saying who must do what.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import sqlalchemy as sa

from edc_bench.errors import ConfigError

#: The folder of Alembic's environment and revisions (shipped inside the package).
MIGRATIONS = Path(__file__).with_name("migrations")

#: The newest revision in ``migrations/versions`` (a test holds it to Alembic's own reading): opening a history
#: that is up to date costs neither Alembic's import nor a scan of the revisions.
HEAD = "0010"

#: PostgreSQL advisory lock taken by an upgrade (here and in migrations/env.py): two owners upgrading take turns.
UPGRADE_LOCK = 724051


@dataclass(frozen=True)
class Revision:
    """One schema change: its id and what it does (the first line of its docstring)."""

    id: str
    summary: str


def _config(connection: sa.Connection | None = None):  # noqa: ANN202 - alembic's Config, imported late
    from alembic.config import Config

    config = Config()
    config.set_main_option("script_location", str(MIGRATIONS))
    config.attributes["connection"] = connection
    return config


def _scripts():  # noqa: ANN202 - alembic's ScriptDirectory
    from alembic.script import ScriptDirectory

    return ScriptDirectory.from_config(_config())


def head() -> str:
    """The revision this edc-bench writes and reads."""
    return HEAD


def current(connection: sa.Connection) -> str | None:
    """The database's revision; None for a database without one (new, or made before revisions)."""
    if not sa.inspect(connection).has_table("alembic_version"):
        return None
    return connection.execute(sa.text("SELECT version_num FROM alembic_version")).scalar()


def pending(revision: str | None) -> list[Revision]:
    """The changes from ``revision`` (None: from nothing) to :func:`head`, oldest first.

    Raises
    ------
    ConfigError
        For a revision this edc-bench does not have (a newer edc-bench made the database).
    """
    if revision is not None and not is_known(revision):
        raise ConfigError(f"the history is at schema revision {revision}, made by a newer edc-bench than this one "
                          f"(revision {HEAD}): update edc-bench here; nothing was changed")
    scripts = _scripts()
    steps = list(scripts.iterate_revisions(head(), revision))  # newest first
    return [Revision(step.revision, (step.doc or "").strip().splitlines()[0]) for step in reversed(steps)]


def is_known(revision: str) -> bool:
    """Whether this edc-bench has ``revision`` (False: a newer edc-bench made the database)."""
    from alembic.util import CommandError

    try:
        return _scripts().get_revision(revision) is not None
    except CommandError:
        return False


def upgrade(engine: sa.Engine) -> list[Revision]:
    """Bring the database to :func:`head`, every change in one transaction; returns the changes made.

    On SQLite the transaction is begun IMMEDIATE: two processes opening a new or older history at once take turns,
    and the second finds nothing left to do. PostgreSQL's migrations take an advisory lock (``migrations/env.py``).
    """
    from alembic import command

    with engine.connect() as connection:
        if engine.dialect.name == "sqlite":
            connection = connection.execution_options(isolation_level="AUTOCOMMIT")  # BEGIN is ours, not the driver's
            connection.exec_driver_sql("BEGIN IMMEDIATE")
            try:
                done = pending(current(connection))
                command.upgrade(_config(connection), "head")
                connection.exec_driver_sql("COMMIT")
            except BaseException:
                connection.exec_driver_sql("ROLLBACK")
                raise
            return done
        from edc_bench.history.roles import apply_grants

        with connection.begin():
            connection.exec_driver_sql(f"SELECT pg_advisory_xact_lock({UPGRADE_LOCK})")  # what is left, once ours
            done = pending(current(connection))
            command.upgrade(_config(connection), "head")
            apply_grants(connection)  # a table a revision added gets the roles' rights at once
        return done


class RevisionMismatch(ConfigError):
    """The database was reached (the login accepted) but is not at this edc-bench's schema revision."""


def require_head(connection: sa.Connection, shown_url: str) -> None:
    """Refuse a database not at this edc-bench's revision, saying who must do what (a shop's PostgreSQL).

    Raises
    ------
    RevisionMismatch
        Saying the database's revision, this edc-bench's, and who upgrades which.
    """
    revision, wanted = current(connection), head()
    if revision == wanted:
        return
    upgrade_cmd = "edc-bench history --upgrade"
    if revision is None:
        has_tests = sa.inspect(connection).has_table("tests")
        raise RevisionMismatch(f"history database {shown_url} "
                          + ("was made by an edc-bench before schema revisions" if has_tests
                             else "holds no edc-bench history yet")
                          + f": its owner's login runs '{upgrade_cmd}' on it first (see 'edc-bench history --schema')")
    if not is_known(revision):
        raise RevisionMismatch(f"history database {shown_url} is at schema revision {revision}, made by a newer "
                          f"edc-bench than this one (revision {wanted}): update edc-bench on this station")
    raise RevisionMismatch(f"history database {shown_url} is at schema revision {revision}; this edc-bench needs "
                      f"{wanted}: its owner's login runs '{upgrade_cmd}' on it (see 'edc-bench history --schema')")
