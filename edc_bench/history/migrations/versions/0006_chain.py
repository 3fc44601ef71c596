"""The chain: each test known by its own id, every row hash-chained; on PostgreSQL the database decides who wrote it.

- tests.test_key: the test's own id (record.json's ``test_id``, schema 8 on). Rows indexed before this revision,
  and records without an id, get a key from what the record says of when, which valve, which pump and where
  (``legacy:`` and the SHA-256 of those four): the only change made to a stored row, done here with the
  append-only triggers held off inside this revision's transaction. A test's content is stored once: a unique
  index on (test_key, record_sha256) for every chained row.
- prev_hash and row_hash on every table (edc_bench.history.chain): each row holds the hash of its chain's row
  before it. The rows already there are *anchored*, not rehashed: one chain_anchors row per chain holds the
  digest of all of them, and the chain's first new row follows that digest.
- tests.legacy_key: what the record says of when, which valve, which pump and where, kept for every row, so a copy
  of a record stripped of its id to look old is still the same test. teardowns.recorded_by: who filed a finding
  (the login's person on PostgreSQL), beside labelled_by (who opened the valve).
- guard_events: what the guard found and did (a SQLite file's triggers found missing or changed, and restored).
- edc_logins: which station (and person) each database login is, kept by the chain's owner
  (``history --map-login``). chain_heads (PostgreSQL): a row per table and chain that the triggers lock.
- PostgreSQL: a trigger on every table sets what a client cannot be trusted with: the id (the sequence's),
  the time (the server's clock), the database login (session_user), the station (the login's mapped station:
  a login with no station may not add tests or rig self-checks), the person of a withdrawal, adoption or
  registration or the filer of a finding (the login's mapped person, else the login), and both hashes. A
  station may not index another station's test with other content, nor check its rig against another station's
  reference valve. The functions run with their owner's rights and a pinned search path (a station's temporary
  table cannot stand in for a table they read), at READ COMMITTED only.
- SQLite: a trigger refuses a row without its hash (the program computes it).

Revision ID: 0006
Revises: 0005
Create Date: 2026-11-27
"""

from __future__ import annotations

import datetime as dt

import sqlalchemy as sa
from alembic import op

revision = "0006"
down_revision = "0005"
branch_labels = None
depends_on = None

#: Chained tables and the column naming a row's chain (edc_bench.history.chain.CHAIN_COLUMN, frozen here).
CHAINED = {"tests": "station", "teardowns": "db_login", "amendments": "db_login", "adoptions": "station",
           "reference_valves": "station", "rig_checks": "station", "guard_events": "db_login"}
NEW_TABLES = ("edc_logins", "chain_anchors", "guard_events")

#: The row's time column, set by the server on PostgreSQL.
TIME_COLUMN = {"tests": "indexed_at", "teardowns": "recorded_at", "amendments": "amended_at",
               "adoptions": "adopted_at", "reference_valves": "registered_at", "rig_checks": "checked_at",
               "guard_events": "happened_at"}
#: The column naming the person who did what the row says (the login's mapped person on PostgreSQL).
PERSON_COLUMN = {"amendments": "amended_by", "adoptions": "adopted_by", "reference_valves": "registered_by",
                 "teardowns": "recorded_by"}

_LEGACY_KEY_SQL = ("'legacy:' || encode(sha256(convert_to(started_at || '|' || valve_id || '|' || pump_serial || "
                   "'|' || station, 'UTF8')), 'hex')")


def _pg_canonical(alias: str) -> str:
    """A row's content as PostgreSQL hashes it: jsonb, empty values and the chain fields left out."""
    return f"(pg_catalog.jsonb_strip_nulls(pg_catalog.to_jsonb({alias})) - 'prev_hash' - 'row_hash')::text"


def _now() -> str:
    return dt.datetime.now(dt.UTC).isoformat(timespec="seconds")


def _append_only_sqlite(bind: sa.Connection, table: str) -> None:
    for event in ("UPDATE", "DELETE"):
        bind.exec_driver_sql(
            f"CREATE TRIGGER IF NOT EXISTS {table}_no_{event.lower()} BEFORE {event} ON {table} BEGIN "
            f"SELECT RAISE(ABORT, 'edc-bench history is append-only: {event} on table {table} refused; "
            "add a correction or a withdrawal instead'); END")


def _chained_sqlite(bind: sa.Connection, table: str) -> None:
    bind.exec_driver_sql(
        f"CREATE TRIGGER IF NOT EXISTS {table}_chained BEFORE INSERT ON {table} WHEN NEW.row_hash IS NULL BEGIN "
        f"SELECT RAISE(ABORT, 'edc-bench history is chained: a row of {table} without its chain hash refused; add "
        "rows with edc-bench'); END")


def _pg_stamp_function(table: str) -> str:
    """The BEFORE INSERT trigger function of ``table`` on PostgreSQL (see the module's docstring).

    SECURITY DEFINER (its owner's rights, ``edc_owner`` once the roles are set up: a station needs no right on
    the sequences or the lock table) with its search path pinned and every name qualified: a station's temporary
    table or view named like one it reads (``pg_temp`` is searched first unless named) cannot stand in for it.
    """
    chain_column = CHAINED[table]
    chain_value = "NEW.station" if chain_column == "station" else "NEW.db_login"
    body = " ".join(_pg_table_checks(table))
    return f"""
CREATE OR REPLACE FUNCTION public.edc_bench_stamp_{table}() RETURNS trigger LANGUAGE plpgsql SECURITY DEFINER
SET search_path = pg_catalog, public, pg_temp AS $fn$
DECLARE
    mapped_station text; mapped_person text; trusted boolean := false; chain_key text; prev text; stamp text;
BEGIN
    IF pg_catalog.current_setting('transaction_isolation') <> 'read committed' THEN
        -- a snapshot older than the chain's last row would write a row that follows a stale one
        RAISE EXCEPTION 'edc-bench history: rows are added at READ COMMITTED, not %',
            pg_catalog.current_setting('transaction_isolation') USING ERRCODE = 'insufficient_privilege';
    END IF;
    SELECT l.station, l.person INTO mapped_station, mapped_person FROM public.edc_logins l
        WHERE l.login = session_user ORDER BY l.id DESC LIMIT 1;
    IF coalesce((SELECT r.rolsuper FROM pg_catalog.pg_roles r WHERE r.rolname = session_user), false) THEN
        trusted := true;
    ELSIF NOT EXISTS (SELECT 1 FROM pg_catalog.pg_roles r WHERE r.rolname = 'edc_owner') THEN
        trusted := true;  -- no roles set up: only the database's owner can write at all
    ELSIF pg_catalog.pg_has_role(session_user, 'edc_owner', 'MEMBER') THEN
        trusted := true;
    END IF;
    stamp := pg_catalog.to_char(pg_catalog.clock_timestamp() AT TIME ZONE 'UTC', 'YYYY-MM-DD"T"HH24:MI:SS')
             || '+00:00';
    NEW.db_login := session_user;
    {body}
    chain_key := coalesce({chain_value}, '');
    -- one writer per chain at a time: the chain's row in chain_heads, locked (no station may lock it: it has no
    -- right to), and the id taken inside the lock, so ids follow the chain's order
    INSERT INTO public.chain_heads (tbl, chain) VALUES ('{table}', chain_key) ON CONFLICT DO NOTHING;
    PERFORM 1 FROM public.chain_heads h WHERE h.tbl = '{table}' AND h.chain = chain_key FOR UPDATE;
    NEW.id := pg_catalog.nextval('public.{table}_id_seq'::pg_catalog.regclass);
    SELECT t.row_hash INTO prev FROM public.{table} t WHERE coalesce(t.{chain_column}, '') = chain_key
        AND t.row_hash IS NOT NULL ORDER BY t.id DESC LIMIT 1;
    IF prev IS NULL THEN
        SELECT a.hash INTO prev FROM public.chain_anchors a WHERE a.tbl = '{table}' AND a.chain = chain_key
            ORDER BY a.id DESC LIMIT 1;
    END IF;
    NEW.prev_hash := coalesce(prev, '');
    NEW.row_hash := NULL;
    NEW.row_hash := pg_catalog.encode(pg_catalog.sha256(pg_catalog.convert_to(NEW.prev_hash || '|{table}|' ||
                                                                              {_pg_canonical('NEW')}, 'UTF8')), 'hex');
    RETURN NEW;
END $fn$"""


def _pg_table_checks(table: str) -> list[str]:
    """The PL/pgSQL statements of ``table``'s stamp that only that table has: its time, station, keys and refusals."""
    specific = [f"NEW.{TIME_COLUMN[table]} := stamp;"]
    if table in ("tests", "rig_checks"):
        what = "tests" if table == "tests" else "rig self-checks"
        specific.append(
            "IF mapped_station IS NOT NULL THEN NEW.station := mapped_station; "
            "ELSIF NOT trusted THEN RAISE EXCEPTION 'edc-bench history: the database login % is mapped to no "
            f"station, so it may not add {what}: the chain''s owner maps it (edc-bench history --map-login % "
            "--station NAME)', session_user, session_user USING ERRCODE = 'insufficient_privilege'; END IF;")
    if table == "tests":
        # a row without its test's keys would group with every other such row: what it says gives them
        new_legacy_key = _LEGACY_KEY_SQL
        for column in ("started_at", "valve_id", "pump_serial", "station"):
            new_legacy_key = new_legacy_key.replace(f"{column} ||" if column != "station" else "|| station",
                                                    f"NEW.{column} ||" if column != "station" else "|| NEW.station")
        specific.append(f"IF NEW.legacy_key IS NULL THEN NEW.legacy_key := {new_legacy_key}; END IF;")
        specific.append("IF NEW.test_key IS NULL THEN NEW.test_key := 'folder:' || NEW.record_dir; END IF;")
        specific.append(
            "IF NOT trusted AND EXISTS (SELECT 1 FROM public.tests t WHERE (t.test_key = NEW.test_key OR t.legacy_key "
            "= NEW.legacy_key) AND t.station <> NEW.station) AND NOT EXISTS (SELECT 1 FROM public.tests t WHERE "
            "t.test_key = NEW.test_key AND t.record_sha256 = NEW.record_sha256) THEN RAISE EXCEPTION 'edc-bench "
            "history: this test was first indexed by another station; station % may not index it with other "
            "content', NEW.station USING ERRCODE = 'insufficient_privilege'; END IF;")
    if table == "rig_checks":
        specific.append(
            "IF NOT EXISTS (SELECT 1 FROM public.reference_valves r WHERE r.id = NEW.reference_id AND r.station = "
            "NEW.station) THEN RAISE EXCEPTION 'edc-bench history: reference valve registration % is not station "
            "%''s: a rig self-check is compared with its own station''s reference valve', NEW.reference_id, "
            "NEW.station USING ERRCODE = 'insufficient_privilege'; END IF;")
    if table == "amendments":
        specific.append(
            "IF NEW.target NOT IN ('tests', 'teardowns') OR (NEW.target = 'tests' AND NOT EXISTS (SELECT 1 FROM "
            "public.tests t WHERE t.id = NEW.target_id)) OR (NEW.target = 'teardowns' AND NOT EXISTS (SELECT 1 FROM "
            "public.teardowns f WHERE f.id = NEW.target_id)) THEN RAISE EXCEPTION 'edc-bench history: a withdrawal "
            "names no stored row (% %)', NEW.target, NEW.target_id USING ERRCODE = 'insufficient_privilege'; END IF;")
    if table in PERSON_COLUMN:
        specific.append(f"IF NOT trusted THEN NEW.{PERSON_COLUMN[table]} := coalesce(mapped_person, session_user); "
                        "END IF;")
    return specific


def _legacy_keys_sqlite(bind: sa.Connection) -> None:
    """Give each test row indexed before this revision its key (edc_bench.history.chain.legacy_test_key)."""
    from edc_bench.history.chain import legacy_test_key

    rows = bind.execute(sa.text("SELECT id, started_at, valve_id, pump_serial, station FROM tests")).all()
    bind.exec_driver_sql("DROP TRIGGER IF EXISTS tests_no_update")
    for row in rows:
        key = legacy_test_key(row.started_at, row.valve_id, row.pump_serial, row.station)
        bind.execute(sa.text("UPDATE tests SET test_key = :k, legacy_key = :k WHERE id = :i"), {"k": key, "i": row.id})
    _append_only_sqlite(bind, "tests")


def _anchor_sqlite(bind: sa.Connection, table: str) -> None:
    """One chain_anchors row per chain of ``table``'s rows: their digest (edc_bench.history.chain.anchor_hash)."""
    from edc_bench.history.chain import anchor_hash

    reflected = sa.Table(table, sa.MetaData(), autoload_with=bind)
    rows = [dict(r._mapping) for r in bind.execute(sa.select(reflected).order_by(reflected.c.id))]
    chains: dict[str, list[dict]] = {}
    for row in rows:
        chains.setdefault(str(row.get(CHAINED[table]) or ""), []).append(row)
    for chain, kept in chains.items():
        bind.execute(sa.text("INSERT INTO chain_anchors (tbl, chain, rows, last_id, hash, made_at) "
                             "VALUES (:t, :c, :n, :l, :h, :m)"),
                     {"t": table, "c": chain, "n": len(kept), "l": kept[-1]["id"], "h": anchor_hash(kept),
                      "m": _now()})


def _anchor_pg(bind: sa.Connection, table: str) -> None:
    chain = f"coalesce(t.{CHAINED[table]}, '')"
    bind.execute(sa.text(
        f"INSERT INTO chain_anchors (tbl, chain, rows, last_id, hash, made_at) SELECT :t, {chain}, count(*), "
        f"max(t.id), encode(sha256(convert_to(string_agg({_pg_canonical('t')}, E'\\n' ORDER BY t.id), 'UTF8')), "
        f"'hex'), :m FROM {table} t GROUP BY {chain}"), {"t": table, "m": _now()})


def upgrade() -> None:
    bind = op.get_bind()
    postgres = bind.dialect.name == "postgresql"
    op.create_table(  # what the history's guard found and did (a station's SQLite triggers restored), kept
        "guard_events",
        sa.Column("id", sa.Integer, primary_key=True, autoincrement=True),
        sa.Column("event", sa.String(40), nullable=False),
        sa.Column("detail", sa.Text, nullable=False),
        sa.Column("happened_at", sa.String(40), nullable=False),
        sa.Column("db_login", sa.String(200)),
    )
    op.add_column("tests", sa.Column("test_key", sa.String(200)))
    op.add_column("tests", sa.Column("legacy_key", sa.String(200)))
    op.add_column("teardowns", sa.Column("recorded_by", sa.String(200)))
    for table in CHAINED:
        op.add_column(table, sa.Column("prev_hash", sa.String(64)))
        op.add_column(table, sa.Column("row_hash", sa.String(64)))
    op.create_table(
        "edc_logins",
        sa.Column("id", sa.Integer, primary_key=True, autoincrement=True),
        sa.Column("login", sa.String(200), nullable=False, index=True),
        sa.Column("station", sa.String(200)),  # None: a login that is no station's (an engineer's)
        sa.Column("person", sa.String(200)),
        sa.Column("mapped_by", sa.String(200), nullable=False),
        sa.Column("mapped_at", sa.String(40), nullable=False),
    )
    op.create_table(
        "chain_anchors",
        sa.Column("id", sa.Integer, primary_key=True, autoincrement=True),
        sa.Column("tbl", sa.String(40), nullable=False),
        sa.Column("chain", sa.String(200), nullable=False),
        sa.Column("rows", sa.Integer, nullable=False),
        sa.Column("last_id", sa.Integer, nullable=False),
        sa.Column("hash", sa.String(64), nullable=False),
        sa.Column("made_at", sa.String(40), nullable=False),
    )
    if postgres:
        bind.exec_driver_sql("ALTER TABLE tests DISABLE TRIGGER tests_append_only")
        bind.exec_driver_sql(f"UPDATE tests SET test_key = {_LEGACY_KEY_SQL}, legacy_key = {_LEGACY_KEY_SQL}")
        bind.exec_driver_sql("ALTER TABLE tests ENABLE TRIGGER tests_append_only")
    else:
        _legacy_keys_sqlite(bind)
    op.create_index("ix_tests_test_key", "tests", ["test_key"])
    op.create_index("ix_tests_legacy_key", "tests", ["legacy_key"])
    # a test's content once: two stations indexing the same copy at once store one row
    op.create_index("ux_tests_test_key_record", "tests", ["test_key", "record_sha256"], unique=True,
                    postgresql_where=sa.text("row_hash IS NOT NULL"), sqlite_where=sa.text("row_hash IS NOT NULL"))
    for table in CHAINED:
        (_anchor_pg if postgres else _anchor_sqlite)(bind, table)
    if postgres:
        # each chain's lock (revision 0006's triggers): a row per table and chain, only the triggers write it
        op.create_table(
            "chain_heads",
            sa.Column("tbl", sa.String(40), primary_key=True),
            sa.Column("chain", sa.String(200), primary_key=True),
        )
        for table in NEW_TABLES:
            bind.exec_driver_sql(f"CREATE TRIGGER {table}_append_only BEFORE UPDATE OR DELETE ON {table} "
                                 "FOR EACH ROW EXECUTE FUNCTION edc_bench_append_only()")
            bind.exec_driver_sql(f"CREATE TRIGGER {table}_no_truncate BEFORE TRUNCATE ON {table} "
                                 "FOR EACH STATEMENT EXECUTE FUNCTION edc_bench_append_only()")
        for table in CHAINED:
            # the id is the trigger's alone (taken inside the chain's lock): no default takes a number before it
            bind.exec_driver_sql(f"ALTER TABLE {table} ALTER COLUMN id DROP DEFAULT")
            bind.exec_driver_sql(_pg_stamp_function(table).replace("%", "%%"))
            bind.exec_driver_sql(f"CREATE TRIGGER {table}_stamp BEFORE INSERT ON {table} FOR EACH ROW "
                                 f"EXECUTE FUNCTION edc_bench_stamp_{table}()")
    else:
        for table in NEW_TABLES:
            _append_only_sqlite(bind, table)
        for table in CHAINED:
            _chained_sqlite(bind, table)
