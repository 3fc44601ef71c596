"""Who may do what in a shop's shared history: PostgreSQL roles, their privileges, and the words for a refusal.

Three group roles, made by ``edc-bench history --setup-roles`` (as the database's owner or a superuser); each
person's or station's login is made a member of one (docs/shop-network.md):

- ``edc_station``: read everything, add tests and rig self-checks;
- ``edc_engineer``: a station's rights, and record teardown findings, withdrawals, model adoptions and reference
  valves (what every later self-check compares with: a station that could register one could make a NO-GO go
  away by registering the drifted rig as the reference);
- ``edc_owner``: owns the tables, so it alone changes the schema (``history --upgrade``) and says which station
  each login is (``history --map-login``: the ``edc_logins`` table, which no other role may add to).

What a row says of who wrote it, when, and where is the database's, not the client's: a trigger of revision 0006
sets the id, the time, the login and the login's mapped station (:mod:`edc_bench.history.chain`).

No role may update or delete a stored row: the privileges are never granted, and the append-only triggers
(:mod:`edc_bench.history.schema`) refuse it to the owner too. SQLite has no logins: a single station's file
is protected by its file permissions and the same triggers.
"""

from __future__ import annotations

from dataclasses import dataclass

import sqlalchemy as sa

STATION, ENGINEER, OWNER = "edc_station", "edc_engineer", "edc_owner"
ROLES = (STATION, ENGINEER, OWNER)

#: The tables each role may add rows to (every role reads every table).
INSERTS = {STATION: ("tests", "rig_checks"), ENGINEER: ("teardowns", "amendments", "adoptions", "reference_valves")}
#: Every table of the history, the migrations' bookkeeping included.
ALL_TABLES = ("tests", "teardowns", "amendments", "adoptions", "reference_valves", "rig_checks", "edc_logins",
              "chain_anchors", "chain_heads", "guard_events", "test_day_counts",
              "test_month_counts", "alembic_version")


@dataclass(frozen=True)
class Right:
    """What an action needs: its words for a person, the role that grants it, and whom to ask if not a role's
    member."""

    words: str
    role: str
    ask: str = ""


#: Actions of the program, the words a refusal uses and the role to ask for.
RIGHTS = {
    "read": Right("read the history", STATION),
    "add-test": Right("add tests", STATION),
    "label": Right("record teardown findings", ENGINEER),
    "withdraw": Right("withdraw tests or findings", ENGINEER),
    "adopt": Right("record model adoptions", ENGINEER),
    "add-rig-check": Right("add rig self-checks", STATION),
    "register-reference": Right("register a reference valve", ENGINEER),
    "upgrade": Right("change the history's schema", OWNER),
    "setup-roles": Right("create the history's roles", OWNER,
                         "ask the database's owner with the CREATEROLE right, or the server's administrator"),
    "map-login": Right("say which station a database login is", OWNER),
}

_WHO = {STATION: "a station's", ENGINEER: "the engineer's", OWNER: "the database owner's"}


def refusal(action: str, login: str | None) -> str:
    """One line for a login refused ``action``: what it may not do and whose login may."""
    right = RIGHTS[action]
    who = f"this station's database login {login!r}" if login else "this station's database login"
    return f"{who} may not {right.words}: " + (right.ask or f"ask {_WHO[right.role]} login (a member of {right.role})")


def _exists(connection: sa.Connection, role: str) -> bool:
    return connection.execute(sa.text("SELECT 1 FROM pg_roles WHERE rolname = :r"), {"r": role}).first() is not None


def setup_roles(connection: sa.Connection) -> list[str]:
    """Create the roles that are missing and grant each its rights on the tables; returns the roles created."""
    created = []
    for role in ROLES:
        if not _exists(connection, role):
            connection.exec_driver_sql(f"CREATE ROLE {role} NOLOGIN")
            created.append(role)
    connection.exec_driver_sql(f"GRANT {STATION} TO {ENGINEER}")
    connection.exec_driver_sql(f"GRANT {OWNER} TO CURRENT_USER")  # so this login may hand the tables to the role
    apply_grants(connection)
    return created


def apply_grants(connection: sa.Connection) -> None:
    """Give the roles their rights on every table there is, and the tables to ``edc_owner``. Run by ``--setup-roles``
    and after every upgrade, so a table a revision adds is covered; a no-op where the roles were not set up, or the
    login is not a member of ``edc_owner`` (the roles belong to the server: another database's owner set them up)."""
    if not all(_exists(connection, role) for role in ROLES):
        return
    may = connection.execute(sa.text("SELECT pg_has_role(current_user, :r, 'MEMBER')"), {"r": OWNER}).scalar()
    if not may:  # the roles are the server's, this database is another's: its owner runs --setup-roles
        return
    present = [t for t in ALL_TABLES if sa.inspect(connection).has_table(t)]
    # nobody else makes objects here: not in the schema (PostgreSQL 14 and older let every login), and no
    # temporary tables, whose names would come first in a search path that does not name pg_temp
    connection.exec_driver_sql("REVOKE CREATE ON SCHEMA public FROM PUBLIC")
    database = connection.execute(sa.text("SELECT current_database()")).scalar()
    connection.exec_driver_sql(f'REVOKE TEMPORARY ON DATABASE "{database}" FROM PUBLIC')
    # first: PostgreSQL hands a table only to a role that may create in its schema
    connection.exec_driver_sql(f"GRANT USAGE ON SCHEMA public TO {STATION}")
    connection.exec_driver_sql(f"GRANT USAGE, CREATE ON SCHEMA public TO {OWNER}")
    for table in present:
        connection.exec_driver_sql(f"REVOKE ALL ON {table} FROM PUBLIC")
        connection.exec_driver_sql(f"GRANT SELECT ON {table} TO {STATION}")
        connection.exec_driver_sql(f"ALTER TABLE {table} OWNER TO {OWNER}")
    for role, tables in INSERTS.items():
        for table in (t for t in tables if t in present):
            connection.exec_driver_sql(f"GRANT INSERT ON {table} TO {role}")
            # the id is the trigger's (its owner's rights): a login needs no number of its own, nor to burn them
            sequence = connection.execute(sa.text("SELECT pg_get_serial_sequence(:t, 'id')"), {"t": table}).scalar()
            if sequence:
                connection.exec_driver_sql(f"REVOKE ALL ON SEQUENCE {sequence} FROM {role}, PUBLIC")
    for (function,) in connection.execute(sa.text("SELECT proname FROM pg_proc WHERE proname LIKE 'edc\\_bench\\_%' "
                                                  "AND pronargs = 0")):
        connection.exec_driver_sql(f"ALTER FUNCTION {function}() OWNER TO {OWNER}")
