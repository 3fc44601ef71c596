"""A station's SQLite history keeps its own guards: the triggers that make it append-only and chained.

SQLite has no logins: whoever can write the file can drop a trigger with the ``sqlite3`` program, change rows,
and leave. So every time edc-bench opens the file it checks that each trigger is there and restores the missing
ones (:func:`restore_triggers`); the store then says loudly that they were missing, and the chain
(:mod:`edc_bench.history.chain`) shows which rows were changed while they were.
"""

from __future__ import annotations

import sqlalchemy as sa

from edc_bench.history.schema import CHAINED_TABLES, SQLITE_TRIGGERS, TABLES


def trigger_sql(name: str) -> str:
    """The CREATE statement of one of the history's triggers (:data:`~edc_bench.history.schema.SQLITE_TRIGGERS`)."""
    for table in TABLES:
        for event in ("update", "delete"):
            if name == f"{table.name}_no_{event}":
                verb = event.upper()
                return (f"CREATE TRIGGER IF NOT EXISTS {name} BEFORE {verb} ON {table.name} BEGIN SELECT RAISE(ABORT, "
                        f"'edc-bench history is append-only: {verb} on table {table.name} refused; add a correction "
                        "or a withdrawal instead'); END")
    for table in CHAINED_TABLES:
        if name == f"{table.name}_chained":
            return (f"CREATE TRIGGER IF NOT EXISTS {name} BEFORE INSERT ON {table.name} WHEN NEW.row_hash IS NULL "
                    f"BEGIN SELECT RAISE(ABORT, 'edc-bench history is chained: a row of {table.name} without its "
                    "chain hash refused; add rows with edc-bench'); END")
    raise KeyError(name)


def _normal(sql: str) -> str:
    """A CREATE TRIGGER statement as SQLite keeps it (without IF NOT EXISTS), its spaces made single."""
    return " ".join(sql.replace("IF NOT EXISTS ", "").split())


def restore_triggers(conn: sa.Connection) -> list[str]:
    """Create the history's triggers that are missing, and make again those that are not what they must be (a
    trigger of the same name that does nothing); returns their names (empty: all there, as they must be)."""
    present = {name: sql or "" for name, sql in
               conn.exec_driver_sql("SELECT name, sql FROM sqlite_master WHERE type = 'trigger'")}
    wrong = [name for name in SQLITE_TRIGGERS if _normal(present.get(name, "")) != _normal(trigger_sql(name))]
    for name in wrong:
        conn.exec_driver_sql(f'DROP TRIGGER IF EXISTS "{name}"')
        conn.exec_driver_sql(trigger_sql(name))
    return wrong


__all__ = ["restore_triggers", "trigger_sql"]
