"""Alembic's entry for the history's migrations: run on the connection edc-bench hands it (history.migrate).

Run by ``edc-bench history --upgrade`` (and on open for a station's SQLite file), never by the ``alembic``
command: the connection comes from ``config.attributes["connection"]``.
"""

from __future__ import annotations

from alembic import context

connection = context.config.attributes["connection"]
context.configure(connection=connection, target_metadata=None, render_as_batch=True)
with context.begin_transaction():
    if connection.dialect.name == "postgresql":
        # two owners upgrading at once: the second waits, then finds the work done
        connection.exec_driver_sql("SELECT pg_advisory_xact_lock(724051)")  # history.migrate.UPGRADE_LOCK
    context.run_migrations()
