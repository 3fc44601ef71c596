"""The station's test history, in SQLite or PostgreSQL: tests as indexed, teardown findings, withdrawals, adoptions.

SQLAlchemy Core speaks to both. SQLite (the default, in the station's data
folder) runs in WAL mode with a busy timeout, so two tests finishing at
once both land and readers never block writers; a shop shares one history
by giving every station the same PostgreSQL URL (docs/shop-network.md).
Each row is written in one transaction, so a writer killed half-way leaves
no partial row.

Nothing stored is changed or deleted (:mod:`edc_bench.history.schema`): a
test is known by the id its record carries, its first indexing stands, and
indexing it again with other content is a row every reader shows as a
change; a withdrawal or a corrected finding is a row naming the row it
concerns. Every row is hash-chained (:mod:`edc_bench.history.chain`).
Readers show the current state; :meth:`HistoryStore.audit` the whole trail.

The records stay the source of truth for tests: the tests table is an
index, and ``edc-bench history --add FOLDER...`` rebuilds it from them.
Teardown findings (``edc-bench label``) live only here: what the shop found
when it opened a valve, the label the classifier can learn from. A teardown
labels the valve's last trustworthy test before it (:meth:`HistoryStore.labelled_tests`).
"""

from __future__ import annotations

import csv
import datetime as dt
import json
import math
import os
import sys
from collections.abc import Callable, Iterable, Iterator, Sequence
from contextlib import AbstractContextManager, contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import IO, TYPE_CHECKING, Any, TypeVar

import sqlalchemy as sa

from edc_bench.errors import ConfigError
from edc_bench.history import migrate
from edc_bench.history.chain import CHAIN_COLUMN, Break, chain_of, check_chain, legacy_test_key, row_hash
from edc_bench.history.guard import database_errors
from edc_bench.history.rows import (
    FINDINGS,
    TEST_ROW_EXTRAS,
    AdoptionRow,
    AuditEvent,
    ChainHead,
    GuardEventRow,
    LoginRow,
    ReferenceRow,
    RigCheckRow,
    TeardownMatch,
    TeardownRow,
    TestRow,
)
from edc_bench.history.schema import (
    CHAINED_TABLES,
    COLUMNS,
    adoptions,
    amendments,
    chain_anchors,
    edc_logins,
    guard_events,
    reference_valves,
    rig_checks,
    teardowns,
    tests,
)
from edc_bench.history.secrets import redact, secrets_of, shown_url
from edc_bench.history.url import check_url, default_url
from edc_bench.records.integrity import file_digest
from edc_bench.records.writer import RECORD_FILE
from edc_bench.section import FeaturePair
from edc_bench.timefmt import local_text
from edc_bench.verdict.verdicts import Verdict

if TYPE_CHECKING:
    from edc_bench.history.rows import _Columns
    from edc_bench.records.schema import Record

_Row = TypeVar("_Row", bound="_Columns")


def _text(value: Any) -> str:
    """``value`` as text any database stores: text that is not valid Unicode (a hand-edited record) escaped."""
    return str(value).encode("utf-8", "backslashreplace").decode("utf-8")


def _finite(value: float | None) -> float | None:
    return value if value is not None and math.isfinite(value) else None


def row_from_record(record: Record, record_dir: Path) -> dict[str, Any]:
    """The history row of a record (record.json's content, typed)."""
    cls, identity, coil, stop = record.classification, record.identity, record.coil, record.stop
    rel = cls.features_rel if cls is not None else FeaturePair()
    fit = record.identification.model_fit if record.identification is not None else None
    model_name = None
    if cls is not None:
        model_name = cls.model_name or (Path(cls.model_file).stem if cls.model_file else None)
    return {
        "record_dir": _text(Path(record_dir).resolve()),
        "started_at": _text(record.started_at),
        "valve_id": _text(record.valve_id),
        "pump_serial": _text(identity.pump_serial),
        "variant": _text(record.variant),
        "part_number": _text(record.part_number),
        "verdict": _text(record.verdict),
        "af_v": _finite(record.features.af),
        "a1_v_s_per_mm": _finite(record.features.a1),
        "af_rel": _finite(rel.af),
        "a1_rel": _finite(rel.a1),
        "probability_faulty": None if cls is None else _finite(cls.probability_faulty),
        "distance": None if cls is None else _finite(cls.distance),
        "station": _text(identity.station),
        "operator": _text(identity.operator),
        "clock": _text(record.clock),
        "software_version": _text(record.software_version),
        "reason": _text(record.loop.abort_reason or (record.reasons[0] if record.reasons else "")),
        "model_name": model_name,
        "model_sha256": None if cls is None else cls.model_sha256,
        "coil_r20_ohm": None if coil is None else _finite(coil.resistance_20c_ohm),
        "coil_in_spec": None if coil is None else coil.in_spec,
        "model_fits": None if fit is None else fit.fits,
        "stop_reason": _text(stop.reason)[:40] if stop is not None and stop.reason else None,
        "test_s": None if stop is None else _finite(stop.time_s),
        "simulated": record.simulated_rig,
        "retest_of": _retest_of(record, record_dir),
        "decision": None if record.retest is None or record.retest.decision is None else str(record.retest.decision),
        "invalid_area": None if record.invalid_area is None else str(record.invalid_area),
        "part": str(record.part_diagnosis.part),
        "test_key": test_key(record),
        # a stripped copy's match; a retest is not its first test, though both may start in the same second
        "legacy_key": legacy_test_key(_text(record.started_at), _text(record.valve_id),
                                      _text(identity.pump_serial), _text(identity.station),
                                      _text(record.retest.of_record) if record.retest is not None else ""),
    }


def test_key(record: Record) -> str:
    """The key the history knows a test by: the id its record carries (schema 8 on), else one made from what the
    record says of when, which valve, which pump and where (:func:`~edc_bench.history.chain.legacy_test_key`)."""
    if record.test_id:
        return _text(record.test_id)[:200]
    return legacy_test_key(_text(record.started_at), _text(record.valve_id), _text(record.identity.pump_serial),
                           _text(record.identity.station))


def _retest_of(record: Record, record_dir: Path) -> str | None:
    """The record folder of the test a retest repeats (it sits beside the retest's folder), as the history names
    folders."""
    if record.retest is None or not record.retest.of_record:
        return None
    return _text(Path(record_dir).resolve().parent / Path(record.retest.of_record).name)


@dataclass(frozen=True)
class Filters:
    """What to list: every given field must match (valve and serial exactly, dates as ISO prefixes)."""

    valve_id: str | None = None
    pump_serial: str | None = None
    variant: str | None = None
    verdict: str | None = None
    since: str | None = None
    until: str | None = None
    #: None: every test; False: only tests on a rig (the simulated rig's left out, as trends and training do)
    simulated: bool | None = None
    station: str | None = None
    #: the technician (the record's operator)
    operator: str | None = None
    #: the shop: its stations (:func:`shop_stations`)
    shop: str | None = None


def filter_clauses(f: Filters) -> list[sa.ColumnElement[bool]]:
    """The conditions on ``tests`` that ``f`` asks for (every listing and every figure of the chain uses these)."""
    clauses: list[sa.ColumnElement[bool]] = []
    for column, value in ((tests.c.valve_id, f.valve_id), (tests.c.pump_serial, f.pump_serial),
                          (tests.c.verdict, f.verdict), (tests.c.station, f.station),
                          (tests.c.operator, f.operator)):
        if value is not None:
            clauses.append(column == value)
    if f.variant is not None:
        clauses.append(sa.or_(tests.c.variant == f.variant, tests.c.part_number == f.variant))
    if f.shop is not None:
        clauses.append(tests.c.station.in_(shop_stations(f.shop)))
    if f.simulated is not None:
        clauses.append(_simulated(f.simulated))
    if f.since is not None:
        clauses.append(tests.c.started_at >= f.since)
    if f.until is not None:
        # a day given alone includes the whole day
        clauses.append(tests.c.started_at <= (f.until if "T" in f.until else f.until + "T99"))
    return clauses


def station_shops() -> sa.Subquery:
    """Each station's shop (``station``, ``shop``): its newest login mapping that names one (revision 0008)."""
    newest = (sa.select(sa.func.max(edc_logins.c.id)).where(edc_logins.c.station.is_not(None),
                                                            edc_logins.c.shop.is_not(None))
              .group_by(edc_logins.c.station))
    return sa.select(edc_logins.c.station, edc_logins.c.shop).where(edc_logins.c.id.in_(newest)).subquery("shops")


def shop_stations(shop: str) -> sa.Select[Any]:
    """The stations of ``shop`` (:func:`station_shops`)."""
    shops = station_shops()
    return sa.select(shops.c.station).where(shops.c.shop == shop)


def first_indexings() -> sa.ColumnElement[bool]:
    """The rows that are their test's first indexing (what it said when first indexed), withdrawn or not."""
    # each row says whether it is (revision 0008), so a filter reads only its own rows; rows stored before it ask
    # whether an earlier row of the same test exists (read per row, through the key's index)
    earlier = tests.alias("earlier")
    before_0008 = sa.and_(tests.c.first_indexing.is_(None),
                          ~sa.exists().where(earlier.c.test_key == tests.c.test_key, earlier.c.id < tests.c.id))
    return sa.or_(tests.c.first_indexing.is_(True), before_0008)


def withdrawn_tests() -> sa.ColumnElement[bool]:
    """The rows of tests that were withdrawn (every row of such a test)."""
    return tests.c.test_key.in_(_withdrawn_keys())


def standing_tests() -> sa.ColumnElement[bool]:
    """The rows that are tests as they stand: each test's first row (what it said when first indexed), unless the
    test was withdrawn."""
    return sa.and_(first_indexings(), tests.c.test_key.not_in(_withdrawn_keys()))


#: The years a day asked for may name (any test's, with room to spare either side).
YEARS = (1900, 9000)


def parse_day(text: str | None, name: str) -> str | None:
    """An ISO date (``2026-11-22``) or date-time, checked; None stays None."""
    if text is None:
        return None
    try:
        when = dt.datetime.fromisoformat(text) if "T" in text else dt.date.fromisoformat(text)
    except ValueError:
        raise ConfigError(f"{name} {text!r} is not a date: write it as YYYY-MM-DD (or YYYY-MM-DDTHH:MM)") from None
    if not YEARS[0] <= when.year <= YEARS[1]:  # a day after it is still a day: no arithmetic overflows
        raise ConfigError(f"{name} {text!r}: give a year from {YEARS[0]} to {YEARS[1]}")
    return when.isoformat()


class HistoryStore:
    """The history database.

    Parameters
    ----------
    url : str, optional
        SQLAlchemy URL: ``sqlite:///path`` or ``postgresql+psycopg://user@host/db``
        (default: :func:`default_url`).
    must_exist : bool, optional
        Refuse a SQLite file named by the URL that does not exist (see :func:`check_url`).
    warn : callable, optional
        Where what opening finds wrong is said (default: a ``warning:`` line on standard error); also kept in
        :attr:`problems`.

    A station's SQLite file is brought to this edc-bench's schema revision when opened; a PostgreSQL history must
    be at it already (its owner runs ``edc-bench history --upgrade``).
    """

    def __init__(self, url: str | None = None, must_exist: bool = False,
                 warn: Callable[[str], None] | None = None) -> None:
        if warn is None:
            warn = _print_warning
        check_url(url, must_exist)
        self.url = url or default_url()
        #: the URL as people may see it: its password masked
        self.shown_url = shown_url(self.url)
        self._secrets = secrets_of(self.url)
        parsed = sa.engine.make_url(self.url)
        self.is_sqlite = parsed.get_backend_name() == "sqlite"
        kwargs: dict[str, Any] = {"hide_parameters": True}  # a driver's error never quotes the row's values
        if self.is_sqlite:
            kwargs["connect_args"] = {"timeout": 30.0}
        else:  # a network gone silent costs seconds, not minutes (the station's settings)
            from edc_bench.history.limits import history_limits

            #: the connection's and each statement's limit
            self.limits = history_limits()
            # no just-in-time compilation: the history's queries are short, and PostgreSQL compiled the chain
            # page's month of a million-row table for 0.7 s to run it in 0.15 s (measured, docs/performance.md)
            connect_args = self.limits.connect_args(server_options="-c jit=off")
            if "options" in parsed.query:  # the URL's own server options come first
                connect_args["options"] = f"{parsed.query['options']} {connect_args['options']}"
                parsed = parsed.difference_update_query(["options"])
            kwargs["connect_args"] = connect_args
        try:
            self.engine = sa.create_engine(parsed, **kwargs)
        except (sa.exc.ArgumentError, ImportError, sa.exc.NoSuchModuleError) as exc:
            raise ConfigError(redact(f"history database {self.shown_url!r}: {exc} (PostgreSQL needs "
                                     "edc-bench[postgres])", self._secrets)) from None
        if self.is_sqlite:
            sa.event.listen(self.engine, "connect", _sqlite_pragmas)
        #: the database login writing rows (PostgreSQL), None on SQLite
        self.login: str | None = None
        #: what opening found wrong (a SQLite file's missing triggers, a broken chain), each said on ``warn``
        self.problems: list[str] = []
        self._warn = warn
        try:
            with self._guard("read"):
                with self.engine.connect() as conn:
                    revision = migrate.current(conn)
                    if not self.is_sqlite:
                        self.login = conn.execute(sa.text("SELECT session_user")).scalar()
                if revision != migrate.head():
                    if self.is_sqlite and (revision is None or migrate.is_known(revision)):
                        migrate.upgrade(self.engine)  # a station's own file: brought up to date as it is opened
                    else:
                        with self.engine.connect() as conn:
                            migrate.require_head(conn, self.shown_url)
                if self.is_sqlite:
                    self._check_sqlite()
        except BaseException:
            self.engine.dispose()  # a history not opened keeps no connection (a web sign-in refused, say)
            raise

    def _check_sqlite(self) -> None:
        """A station's file is append-only only while its triggers are there: restore any missing, say so loudly,
        and check the chain (a row changed while they were gone breaks it)."""
        from edc_bench.history.sqlite_guard import restore_triggers

        with self._writing("read") as conn:
            restored = restore_triggers(conn)
            if restored:  # kept in the history itself: said by every --verify after, not only to whoever opens it now
                self._append(conn, guard_events, {"event": "triggers restored", "detail": ", ".join(restored),
                                                  "happened_at": _now(), "db_login": None})
        if restored:
            self._say(f"history database {self.shown_url}: its append-only triggers were missing or changed "
                      f"({len(restored)}: {', '.join(restored)}); someone may have changed or deleted rows meanwhile: "
                      "restored now; 'edc-bench history --verify' shows where its chain breaks")
        breaks = self._chain_breaks_since_checked(full=bool(restored))
        if breaks:
            self._say(f"history database {self.shown_url}: its chain is broken in {len(breaks)} place(s), first "
                      f"{breaks[0].line()}: rows were changed, deleted or put in by hand; 'edc-bench history "
                      "--verify' lists them")

    def _say(self, problem: str) -> None:
        self.problems.append(problem)
        if self._warn is not None:
            self._warn(problem)

    def _guard(self, action: str) -> AbstractContextManager[None]:
        """Database errors as one line a person can act on: a refused right names whose login has it."""
        return database_errors(action, self.shown_url, self._secrets, self.login)

    @contextmanager
    def reading(self) -> Iterator[sa.Connection]:
        """A connection to read with, its database errors said as one line (a login refused names who may)."""
        with self._guard("read"), self.engine.connect() as conn:
            yield conn

    @contextmanager
    def _writing(self, action: str) -> Iterator[sa.Connection]:
        """One transaction that writes: on SQLite begun IMMEDIATE, so that reading a chain's last row and adding the
        next is one step no other writer comes between (PostgreSQL's trigger takes a lock per chain)."""
        with self._guard(action):
            if not self.is_sqlite:
                with self.engine.begin() as conn:
                    yield conn
                return
            with self.engine.connect() as plain:
                conn = plain.execution_options(isolation_level="AUTOCOMMIT")  # BEGIN is ours, not the driver's
                conn.exec_driver_sql("BEGIN IMMEDIATE")
                try:
                    yield conn
                except BaseException:
                    conn.exec_driver_sql("ROLLBACK")
                    raise
                conn.exec_driver_sql("COMMIT")

    def _append(self, conn: sa.Connection, table: sa.Table, row: dict[str, Any]) -> dict[str, Any] | None:
        """Add one row to its chain; returns it as stored (None: the same test's content was stored meanwhile).

        PostgreSQL's trigger sets the id, the time, the login, the station and the hashes itself (what the row
        says of them is not trusted); on SQLite they are computed here, inside :meth:`_writing`'s lock.
        """
        if not self.is_sqlite:
            from sqlalchemy.dialects.postgresql import insert

            statement = insert(table).values(**row)
            if table is tests:
                statement = statement.on_conflict_do_nothing(index_elements=[tests.c.test_key, tests.c.record_sha256],
                                                             index_where=tests.c.row_hash.is_not(None))
            stored = conn.execute(statement.returning(*table.c)).first()
            return None if stored is None else dict(stored._mapping)
        row = _typed(table, {key: value for key, value in row.items() if key != "id"})
        row["id"] = int(conn.execute(sa.select(sa.func.coalesce(sa.func.max(table.c.id), 0) + 1)).scalar() or 1)
        chain = chain_of(table.name, row)
        row["prev_hash"] = self._chain_head(conn, table, chain)
        row["row_hash"] = row_hash(table.name, row["prev_hash"], row)
        conn.execute(table.insert().values(**row))
        return row

    @staticmethod
    def _chain_head(conn: sa.Connection, table: sa.Table, chain: str) -> str:
        """The hash a new row of ``chain`` follows: its last row's, else its anchor's, else ''."""
        column = table.c[CHAIN_COLUMN[table.name]]
        last = conn.execute(sa.select(table.c.row_hash).where(sa.func.coalesce(column, "") == chain,
                                                             table.c.row_hash.is_not(None))
                            .order_by(table.c.id.desc()).limit(1)).scalar()
        if last is not None:
            return str(last)
        anchor = conn.execute(sa.select(chain_anchors.c.hash).where(chain_anchors.c.tbl == table.name,
                                                                   chain_anchors.c.chain == chain)
                              .order_by(chain_anchors.c.id.desc()).limit(1)).scalar()
        return str(anchor or "")

    def close(self) -> None:
        """Release connections."""
        self.engine.dispose()

    def __enter__(self) -> HistoryStore:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- tests -------------------------------------------------------------------------------------------------

    def add(self, record: Record, record_dir: Path, indexed_by: str | None = None) -> str:
        """Index one record folder; returns ``new``, ``changed`` (indexed before with other content: a new row),
        ``unchanged`` (indexed before as it is: nothing written) or ``withdrawn`` (its test was withdrawn, and stays
        so: nothing written).

        The row keeps the SHA-256 of the folder's record.json as read and its integrity manifest (``--verify``).
        """
        row = row_from_record(record, record_dir)
        path = Path(record_dir) / RECORD_FILE
        row["record_sha256"] = file_digest(path) if path.is_file() else None
        row["record_manifest"] = json.dumps(record.integrity, sort_keys=True) if record.integrity else None
        return self.add_row(row, indexed_by)

    def add_row(self, row: dict[str, Any], indexed_by: str | None = None) -> str:
        """Store one test's row (:func:`row_from_record`); see :meth:`add`.

        A test is known by its key (``test_key``: the id its record carries), not by its folder: a copy of the
        folder elsewhere is the same test, a withdrawal follows it, and its first indexing stands. The content is
        stored once (a unique key on the test and its record's hash): two stations indexing the same copy at once
        store one row.
        """
        row = {**{key: value for key, value in row.items() if key not in TEST_ROW_EXTRAS},  # a listed row given back
               "indexed_at": _now(), "indexed_by": indexed_by or _login_name(), "db_login": self.login}
        if not row.get("test_key"):  # a row made by hand (the simulated shop's): its folder names the test
            row["test_key"] = "folder:" + str(row["record_dir"])
        if not row.get("legacy_key"):
            row["legacy_key"] = legacy_test_key(*(_text(row.get(name) or "") for name in
                                                  ("started_at", "valve_id", "pump_serial", "station")))
        with self._writing("add-test") as conn:
            # the same when, valve, pump and place is the same test, whatever id its record carries now (a copy
            # stripped of its id to look old): it keeps the key it was first indexed under
            first = conn.execute(sa.select(tests.c.test_key).where(tests.c.legacy_key == row["legacy_key"])
                                 .order_by(tests.c.id).limit(1)).scalar()
            if first is not None:
                row["test_key"] = first
            key = row["test_key"]
            if conn.execute(sa.select(tests.c.id).where(tests.c.test_key == key,
                                                        tests.c.id.in_(_withdrawn("tests")))).first():
                return "withdrawn"
            before = [dict(r._mapping) for r in conn.execute(sa.select(tests).where(tests.c.test_key == key)
                                                            .order_by(tests.c.id))]
            if any(_same_test(stored, row) for stored in before):
                return "unchanged"
            # whether this is the test's first indexing: PostgreSQL's trigger sets it again (a client is not trusted)
            if self._append(conn, tests, {**row, "first_indexing": not before}) is None:
                return "unchanged"  # another station stored this content a moment ago
        return "new" if not before else "changed"

    def _current_tests(self) -> sa.ColumnElement[bool]:
        """The rows that are tests as they stand (:func:`standing_tests`)."""
        return standing_tests()

    @staticmethod
    def _changes() -> sa.ScalarSelect[Any]:
        """How many times a test was indexed again with other content after its first indexing (a correlated
        count for the listing: every reader shows it)."""
        later = tests.alias("later")
        return (sa.select(sa.func.count()).where(later.c.test_key == tests.c.test_key, later.c.id > tests.c.id)
                .scalar_subquery())

    def list(self, filters: Filters = Filters(), limit: int | None = None) -> list[TestRow]:
        """Tests as they stand matching ``filters``, oldest first (the newest ``limit`` if given)."""
        query = sa.select(*(tests.c[name] for name in COLUMNS), self._changes().label("changes"),
                          tests.c.row_hash.label("chain_hash")).where(self._current_tests())
        query = query.where(*filter_clauses(filters)).order_by(tests.c.started_at.desc(), tests.c.id.desc())
        if limit is not None:
            query = query.limit(limit)
        return self._rows(query, TestRow)[::-1]

    def indexed(self, station: str | None = None) -> list[TestRow]:
        """Every test as it stands (of one station if given) with how it was first indexed (record hash and
        manifest), for ``--verify``."""
        query = sa.select(tests).where(self._current_tests())
        if station is not None:
            query = query.where(tests.c.station == station)
        return self._rows(query.order_by(tests.c.id), TestRow)

    def first_indexing(self, key: str) -> TestRow | None:
        """The row that first indexed the test ``key`` (the one that stands), with ``changes``: how many times it was
        indexed again with other content; None if the history does not hold the test."""
        found = self._rows(sa.select(tests, self._changes().label("changes")).where(tests.c.test_key == key)
                           .order_by(tests.c.id).limit(1), TestRow)
        return found[0] if found else None

    def adoptions(self) -> list[AdoptionRow]:
        """Every adoption, oldest first (``train --adopt``)."""
        return self._rows(sa.select(adoptions).order_by(adoptions.c.id), AdoptionRow)

    def guard_events(self) -> list[GuardEventRow]:
        """What the guard found and did, oldest first (a SQLite file's triggers restored)."""
        return self._rows(sa.select(guard_events).order_by(guard_events.c.id), GuardEventRow)

    def changed_tests(self, station: str | None = None) -> list[TestRow]:
        """Rows that indexed a test again with other content than its first indexing (of one station's tests if
        given), oldest first, each with ``first_id``: the row that stands."""
        first = tests.alias("first")
        query = (sa.select(tests, first.c.id.label("first_id"))
                 .join(first, sa.and_(first.c.test_key == tests.c.test_key, first.c.id < tests.c.id))
                 .where(first.c.id.in_(sa.select(sa.func.min(tests.c.id)).group_by(tests.c.test_key))))
        if station is not None:
            query = query.where(first.c.station == station)
        return self._rows(query.order_by(tests.c.id), TestRow)

    def chain_breaks(self, station: str | None = None) -> list[Break]:
        """Where the history's chains break (:func:`~edc_bench.history.chain.check_chain`): of one station's
        chains if given. PostgreSQL recomputes each row's hash itself; SQLite's are recomputed here."""
        found: list[Break] = []
        with self._guard("read"), self.engine.connect() as conn:
            for table in CHAINED_TABLES:
                column = table.c[CHAIN_COLUMN[table.name]]
                query = sa.select(table)
                if station is not None:
                    if CHAIN_COLUMN[table.name] != "station":
                        continue
                    query = query.where(column == station)
                rows = [dict(r._mapping) for r in conn.execute(query.order_by(table.c.id))]
                anchors = _anchors(conn, table.name, station)
                recomputed = legacy = None
                if not self.is_sqlite:
                    recomputed, legacy = _pg_recomputed(conn, table.name, anchors)
                found += check_chain(table.name, rows, anchors, recomputed, legacy)
        return found

    def altered_tests(self, ids: Sequence[int]) -> set[int]:
        """Which of the test rows ``ids`` are not as their chain stored them: the row's content hashed again is not
        its ``row_hash``, or its ``prev_hash`` is not the hash of the row before it in its chain (a row put in or
        taken out there). A few rows (a valve's page); ``history --verify`` checks every chain whole."""
        wanted = [int(i) for i in ids]
        if not wanted:
            return set()
        earlier = tests.alias("earlier")
        before = (sa.select(earlier.c.row_hash).where(earlier.c.station == tests.c.station, earlier.c.id < tests.c.id,
                                                      earlier.c.row_hash.is_not(None))
                  .order_by(earlier.c.id.desc()).limit(1).scalar_subquery())
        anchor = (sa.select(chain_anchors.c.hash).where(chain_anchors.c.tbl == "tests",
                                                       chain_anchors.c.chain == sa.func.coalesce(tests.c.station, ""))
                  .order_by(chain_anchors.c.id.desc()).limit(1).scalar_subquery())
        altered: set[int] = set()
        with self._guard("read"), self.engine.connect() as conn:
            rows = conn.execute(sa.select(tests, before.label("chain_before"), anchor.label("anchor"))
                                .where(tests.c.id.in_(wanted), tests.c.row_hash.is_not(None))).all()
            if not self.is_sqlite:
                recomputed = dict(conn.execute(sa.text(f"SELECT t.id, {_pg_row_hash('tests')} FROM tests t "
                                                       "WHERE t.id = ANY(:ids)"), {"ids": wanted}).all())
        for row in rows:
            content = {k: v for k, v in row._mapping.items() if k not in ("chain_before", "anchor")}
            again = recomputed.get(row.id) if not self.is_sqlite else row_hash("tests", row.prev_hash or "", content)
            follows = row.chain_before if row.chain_before is not None else (row.anchor or "")
            if again != row.row_hash or (row.prev_hash or "") != follows:
                altered.add(int(row.id))
        return altered

    def first_indexing_mismatches(self, station: str | None = None) -> list[str]:
        """The test rows whose ``first_indexing`` is not what the rows before them say (one line each): a row that
        says it is its test's first indexing though an earlier row of the test exists, or says it repeats a test
        no earlier row holds. Readers trust the value (it decides which rows are the tests as they stand), so
        ``history --verify`` holds every row to it; on PostgreSQL only the trigger sets it."""
        earlier = tests.alias("earlier")
        exists_earlier = sa.exists().where(earlier.c.test_key == tests.c.test_key, earlier.c.id < tests.c.id)
        query = (sa.select(tests.c.id, tests.c.test_key, tests.c.first_indexing)
                 .where(sa.or_(sa.and_(tests.c.first_indexing.is_(True), exists_earlier),
                               sa.and_(tests.c.first_indexing.is_(False), ~exists_earlier)))
                 .order_by(tests.c.id))
        if station is not None:
            query = query.where(tests.c.station == station)
        with self._guard("read"), self.engine.connect() as conn:
            found = conn.execute(query).all()
        return [f"tests row {row.id} says it is " + ("the first indexing of its test, but an earlier row indexed it"
                                                     if row.first_indexing else
                                                     "its test indexed again, but no earlier row indexed it")
                + ": the tests shown as standing would be wrong (the row was written outside edc-bench)"
                for row in found]

    def _chain_breaks_since_checked(self, full: bool) -> list[Break]:
        """The SQLite chain's breaks, checked in full at this process's first opening of the file (and after its
        triggers were restored), then only in the rows added since: a shift's session opens the history for every
        test, and a year's rows cost it a second each time. ``history --verify`` always checks in full."""
        try:
            stat = os.stat(self.engine.url.database or "")
            key: tuple[str, int, int] | None = (os.path.realpath(self.engine.url.database or ""), stat.st_dev,
                                                stat.st_ino)
        except OSError:  # an in-memory database, or a file that cannot be looked at: checked in full
            key = None
        checked = None if full or key is None else _CHECKED.get(key)
        found: list[Break] = []
        heads: dict[str, tuple[int, dict[str, str]]] = {}
        with self._guard("read"), self.engine.connect() as conn:
            for table in CHAINED_TABLES:
                since_id, verified = checked[table.name] if checked is not None else (0, None)
                rows = [dict(r._mapping) for r in conn.execute(sa.select(table).where(table.c.id > since_id)
                                                               .order_by(table.c.id))]
                found += check_chain(table.name, rows, _anchors(conn, table.name, None), verified_heads=verified)
                last = dict(verified or {})
                for row in rows:
                    if row.get("row_hash") is not None:
                        last[chain_of(table.name, row)] = str(row["row_hash"])
                heads[table.name] = (max([since_id, *(int(row["id"]) for row in rows)]), last)
        if key is not None and not found:  # a break is looked for again at every opening until it is mended
            _CHECKED[key] = heads
        return found

    def heads(self) -> list[ChainHead]:
        """Each chain's last row (table, chain, id, row_hash): what a shop keeps outside the station (``history
        --heads``) so that a history rewritten whole is caught (``history --verify --heads FILE``)."""
        heads = []
        with self._guard("read"), self.engine.connect() as conn:
            for table in CHAINED_TABLES:
                column = sa.func.coalesce(table.c[CHAIN_COLUMN[table.name]], "")
                last = sa.select(sa.func.max(table.c.id)).where(table.c.row_hash.is_not(None)).group_by(column)
                for r in conn.execute(sa.select(table.c.id, column.label("chain"), table.c.row_hash)
                                      .where(table.c.id.in_(last)).order_by(table.c.id)):
                    heads.append(ChainHead(table.name, str(r.chain), int(r.id), str(r.row_hash)))
        return heads

    def missing_heads(self, heads: list[ChainHead]) -> list[str]:
        """The heads kept outside the station (:meth:`heads`, as written then) that this history no longer holds
        as they were: each one line."""
        missing = []
        with self._guard("read"), self.engine.connect() as conn:
            for head in heads:
                table = {t.name: t for t in CHAINED_TABLES}.get(head.table)
                if table is None:
                    missing.append(f"a kept head names no table of the history: {head.table!r}")
                    continue
                stored = conn.execute(sa.select(table.c.row_hash).where(table.c.id == head.id)).scalar()
                if stored != head.row_hash:
                    missing.append(f"row {head.id} of {table.name} (chain {head.chain or '(none)'}): "
                                   + ("gone" if stored is None else "not the row it was")
                                   + " since its head was kept: the history was rewritten")
        return missing

    # -- who each login is (the chain's owner keeps it) -----------------------------------------------------------

    def map_login(self, login: str, station: str | None, person: str | None, by: str,
                  shop: str | None = None) -> LoginRow:
        """Say which station (and person) a database login is (``history --map-login``): from then on the database
        writes that station into every test and rig self-check the login adds, and that person into its
        withdrawals, adoptions and registrations. A login's newest mapping stands. ``shop``: the shop the station
        belongs to (a station's newest mapping that names a shop stands: :func:`shop_stations`). The owner's login
        only."""
        row = {"login": login, "station": station, "person": person, "mapped_by": by, "mapped_at": _now(),
               "shop": shop}
        with self._writing("map-login") as conn:
            row_id = conn.execute(edc_logins.insert().values(**row)).inserted_primary_key[0]
        return LoginRow.of({**row, "id": row_id})

    def logins(self) -> list[LoginRow]:
        """Each login's mapping as it stands (its newest), by login."""
        newest = sa.select(sa.func.max(edc_logins.c.id)).group_by(edc_logins.c.login)
        return self._rows(sa.select(edc_logins).where(edc_logins.c.id.in_(newest)).order_by(edc_logins.c.login),
                          LoginRow)

    @property
    def station(self) -> str | None:
        """The station this database login is mapped to (PostgreSQL; None on SQLite or where it is mapped to
        none): the name the database writes into its rows."""
        if self.is_sqlite or self.login is None:
            return None
        with self._guard("read"), self.engine.connect() as conn:
            return conn.execute(sa.select(edc_logins.c.station).where(edc_logins.c.login == self.login)
                                .order_by(edc_logins.c.id.desc()).limit(1)).scalar()

    def withdraw_test(self, test_id: int, reason: str, by: str | None = None) -> TestRow:
        """Withdraw a test (its id from ``history``): it leaves listings, trends and training; ``--audit`` keeps it.
        Returns the test's row."""
        with self._writing("withdraw") as conn:
            found = conn.execute(sa.select(tests).where(tests.c.id == test_id)).first()
            if found is None:
                raise ConfigError(f"no test with id {test_id} in {self.shown_url} (see 'edc-bench history')")
            # the test, not the row: every row of its key (a copy of its folder, a change) is withdrawn with it
            if conn.execute(sa.select(tests.c.id).where(tests.c.test_key == found.test_key,
                                                        tests.c.test_key.in_(_withdrawn_keys()))).first():
                raise ConfigError(f"test {test_id} (valve {found.valve_id!r}) is withdrawn already "
                                  f"(see 'edc-bench history --audit {found.valve_id}')")
            self._append(conn, amendments, {"target": "tests", "target_id": test_id, "action": "withdraw",
                                            "reason": reason, "amended_by": by or _login_name(), "amended_at": _now(),
                                            "db_login": self.login})
        return TestRow.of(found._mapping)

    # -- teardowns ---------------------------------------------------------------------------------------------

    def add_teardown(self, valve_id: str, finding: str, *, labelled_by: str, labelled_at: str,
                     clearance_mm: float | None = None, note: str = "", corrects: int | None = None) -> TeardownRow:
        """Record what a teardown of ``valve_id`` found; returns the stored row.

        Parameters
        ----------
        valve_id : str
            The valve, as its tests name it.
        finding : str
            ``reusable``, ``worn`` or ``faulty`` (:data:`FINDINGS`).
        labelled_by : str
            Who opened the valve.
        labelled_at : str
            When (ISO date or date-time, UTC).
        clearance_mm : float, optional
            The plunger clearance measured.
        note : str
            Anything else found.
        corrects : int, optional
            The id of a finding of this valve that this one replaces (recorded by mistake).
        """
        if finding not in FINDINGS:
            raise ConfigError(f"teardown finding {finding!r}: use one of {', '.join(FINDINGS)}")
        row = {"valve_id": valve_id, "finding": finding, "clearance_mm": clearance_mm, "note": note,
               "labelled_by": labelled_by, "labelled_at": labelled_at, "recorded_at": _now(),
               "corrects_id": corrects, "db_login": self.login,
               "recorded_by": _login_name()}  # on PostgreSQL the database writes the login's person instead
        with self._writing("label") as conn:
            if corrects is not None:
                self._current_teardown(conn, corrects, valve_id)
            stored = self._append(conn, teardowns, row)
        return TeardownRow.of(_shown(stored or row))

    def _current_teardown(self, conn: sa.Connection, teardown_id: int, valve_id: str | None = None) -> Any:
        """The finding ``teardown_id`` if it stands (not withdrawn nor corrected); a ConfigError saying why not."""
        found = conn.execute(sa.select(teardowns).where(teardowns.c.id == teardown_id)).first()
        if found is None or (valve_id is not None and found.valve_id != valve_id):
            of = f" of valve {valve_id!r}" if valve_id is not None else ""
            raise ConfigError(f"no teardown finding with id {teardown_id}{of} (see 'edc-bench label --list')")
        if teardown_id not in {r.id for r in self._standing_teardowns(conn)}:
            raise ConfigError(f"teardown finding {teardown_id} is withdrawn or corrected already (see 'edc-bench "
                              f"history --audit {found.valve_id}')")
        return found

    def withdraw_teardown(self, teardown_id: int, reason: str, by: str | None = None) -> TeardownRow:
        """Withdraw a finding recorded by mistake (its id from ``label --list``); returns it."""
        with self._writing("withdraw") as conn:
            found = self._current_teardown(conn, teardown_id)
            self._append(conn, amendments, {"target": "teardowns", "target_id": teardown_id, "action": "withdraw",
                                            "reason": reason, "amended_by": by or _login_name(), "amended_at": _now(),
                                            "db_login": self.login})
        return TeardownRow.of(found._mapping)

    def _standing_teardowns(self, conn: sa.Connection, valve_id: str | None = None) -> list[TeardownRow]:
        query = sa.select(teardowns)  # the whole row: a TeardownRow holds no field the query left out
        if valve_id is not None:
            query = query.where(teardowns.c.valve_id == valve_id)
        rows = [TeardownRow.of(r._mapping) for r in conn.execute(query.order_by(teardowns.c.labelled_at,
                                                                                teardowns.c.id))]
        withdrawn = {r[0] for r in conn.execute(_withdrawn("teardowns"))}
        # (id, the finding it corrects) of every finding
        every = conn.execute(sa.select(teardowns.c.id, teardowns.c.corrects_id)).all()
        corrected = {corrects for row_id, corrects in every if corrects is not None and row_id not in withdrawn}
        return [r for r in rows if r.id not in withdrawn and r.id not in corrected]

    def teardowns(self, valve_id: str | None = None) -> list[TeardownRow]:
        """Teardown findings as they stand (of one valve if given), in the order of the teardowns."""
        with self._guard("read"), self.engine.connect() as conn:
            return self._standing_teardowns(conn, valve_id)

    def labelled_tests(self, include_simulated: bool = False) -> list[TeardownMatch]:
        """Every teardown with the test it labels, oldest first.

        A teardown labels the valve's last test before it that was judged on
        its features (not INVALID, relative features known): the valve as the
        bench last saw it; a teardown given as a date alone counts that whole
        day. Each test is labelled once: a second teardown of the valve labels
        only a test after the first. Teardowns with no such test are
        left out (:meth:`unmatched_teardowns` lists them). Withdrawn tests and
        findings, and findings corrected since, count for nothing; tests on
        the simulated rig neither, unless ``include_simulated``.
        """
        return [match for match in self.teardown_matches(include_simulated) if match.test is not None]

    def unmatched_teardowns(self, include_simulated: bool = False) -> list[TeardownMatch]:
        """Teardowns of valves with no test judged before them (nothing to learn from yet)."""
        return [match for match in self.teardown_matches(include_simulated) if match.test is None]

    def teardown_matches(self, include_simulated: bool = False) -> list[TeardownMatch]:
        """Every teardown in order, with the test it labels (:meth:`labelled_tests`), None if none."""
        found = self.teardowns()
        valves = sorted({t.valve_id for t in found})
        query = sa.select(*(tests.c[name] for name in COLUMNS)).where(
            self._current_tests(), tests.c.valve_id.in_(valves), tests.c.af_rel.is_not(None),
            tests.c.a1_rel.is_not(None), tests.c.verdict != Verdict.INVALID).order_by(tests.c.started_at, tests.c.id)
        if not include_simulated:
            query = query.where(_simulated(False))
        by_valve: dict[str, list[TestRow]] = {}
        for test in (self._rows(query, TestRow) if valves else []):
            by_valve.setdefault(test.valve_id, []).append(test)
        matches = []
        previous: dict[str, str] = {}  # valve -> bound of its previous teardown
        for teardown in found:
            valve = teardown.valve_id
            # a date alone counts the whole day: the valve tested in the morning and opened in the afternoon
            bound = teardown.labelled_at if "T" in teardown.labelled_at else teardown.labelled_at + "T99"
            # a test labels once: the test after the valve's previous teardown and before this one
            after = previous.get(valve, "")
            between = [t for t in by_valve.get(valve, []) if after < t.started_at <= bound]
            previous[valve] = bound
            matches.append(TeardownMatch(teardown, between[-1] if between else None))
        return matches

    def trend(self, valve_id: str, include_simulated: bool = False) -> list[TestRow]:
        """Every trustworthy visit of one valve, oldest first (on a rig; the simulated rig's too if asked)."""
        filters = Filters(valve_id=valve_id, simulated=None if include_simulated else False)
        return [r for r in self.list(filters) if r.verdict != Verdict.INVALID]

    # -- the whole chain ---------------------------------------------------------------------------------------

    def audit(self, valve_id: str) -> list[AuditEvent]:
        """Everything the history holds of one valve, in the order it was written: each indexing of its tests,
        each finding, each correction and withdrawal, with who and when and its row's chain hash
        (:class:`~edc_bench.history.rows.AuditEvent`)."""
        with self._guard("read"), self.engine.connect() as conn:
            rows = [TestRow.of(r._mapping) for r in conn.execute(
                sa.select(tests).where(tests.c.valve_id == valve_id).order_by(tests.c.id))]
            found = [TeardownRow.of(r._mapping) for r in conn.execute(
                sa.select(teardowns).where(teardowns.c.valve_id == valve_id).order_by(teardowns.c.id))]
            changes = conn.execute(sa.select(amendments).where(sa.or_(
                sa.and_(amendments.c.target == "tests", amendments.c.target_id.in_([r.id for r in rows])),
                sa.and_(amendments.c.target == "teardowns", amendments.c.target_id.in_([t.id for t in found])),
            )).order_by(amendments.c.id)).all()
        return audit_events(rows, found, changes)

    def add_adoption(self, model_name: str, model_sha256: str, station: str, adopted_by: str,
                     then: Callable[[], object] | None = None, evaluation: str | None = None) -> AdoptionRow:
        """Record that ``station`` now judges with a model (``edc-bench train --adopt``); returns the row.

        ``evaluation``: what the adoption was decided on (a shop candidate's
        :class:`~edc_bench.learning.shop_training.CandidateEvaluation` as JSON), None for a model without one.

        ``then`` (the station's own change) runs after the row is written and before it is committed: a login that
        may not adopt is refused before the station changes, and a station change that fails leaves no row.
        """
        row = {"station": station, "model_name": model_name, "model_sha256": model_sha256, "adopted_by": adopted_by,
               "adopted_at": _now(), "db_login": self.login, "evaluation": evaluation}
        with self._writing("adopt") as conn:
            stored = self._append(conn, adoptions, row)
            if then is not None:
                then()
        return AdoptionRow.of(_shown(stored or row))

    # -- the rig self-check's ledger ----------------------------------------------------------------------------

    def add_reference(self, row: dict[str, Any]) -> ReferenceRow:
        """Register a station's reference valve (``edc-bench rig-selfcheck --register``); returns the stored row.

        ``row`` holds the columns of :data:`~edc_bench.history.schema.reference_valves` but ``id``,
        ``registered_at`` and ``db_login``. A registration again is a new row: the station's newest stands, the
        earlier ones stay (and the checks made against them).
        """
        row = {**row, "registered_at": _now(), "db_login": self.login}
        with self._writing("register-reference") as conn:
            stored = self._append(conn, reference_valves, row)
        return ReferenceRow.of(_shown(stored or row))

    def reference(self, station: str) -> ReferenceRow | None:
        """The station's reference valve as it stands (its newest registration), or None if it has none."""
        query = (sa.select(reference_valves).where(reference_valves.c.station == station)
                 .order_by(reference_valves.c.id.desc()).limit(1))
        found = self._rows(query, ReferenceRow)
        return found[0] if found else None

    def add_rig_check(self, row: dict[str, Any]) -> RigCheckRow:
        """Store one rig self-check; returns the stored row (columns of :data:`~edc_bench.history.schema.rig_checks`
        but ``id``, ``checked_at`` and ``db_login``)."""
        row = {**row, "checked_at": _now(), "db_login": self.login}
        with self._writing("add-rig-check") as conn:
            stored = self._append(conn, rig_checks, row)
        return RigCheckRow.of(_shown(stored or row))

    def rig_checks(self, station: str | None = None, reference_id: int | None = None) -> list[RigCheckRow]:
        """Rig self-checks, oldest first: of one station and one registration if given."""
        query = sa.select(rig_checks)
        if station is not None:
            query = query.where(rig_checks.c.station == station)
        if reference_id is not None:
            query = query.where(rig_checks.c.reference_id == reference_id)
        return self._rows(query.order_by(rig_checks.c.id), RigCheckRow)

    def references(self, station: str | None = None) -> list[ReferenceRow]:
        """Every registration, oldest first (of one station if given)."""
        query = sa.select(reference_valves)
        if station is not None:
            query = query.where(reference_valves.c.station == station)
        return self._rows(query.order_by(reference_valves.c.id), ReferenceRow)

    def tests_since(self, station: str, since: str) -> int:
        """Tests of ``station`` that started after ``since`` (an ISO time), withdrawn ones too: what the self-check's
        due rule counts (:func:`edc_bench.selfcheck.due.selfcheck_due`)."""
        query = sa.select(sa.func.count(sa.distinct(tests.c.test_key))).where(
            tests.c.station == station, tests.c.started_at > since)
        with self._guard("read"), self.engine.connect() as conn:
            return int(conn.execute(query).scalar() or 0)

    def _rows(self, query: sa.Select[Any], row_type: type[_Row]) -> list[_Row]:
        """The query's rows as ``row_type``."""
        with self._guard("read"), self.engine.connect() as conn:
            return [row_type.of(r._mapping) for r in conn.execute(query)]


#: The columns that say how a row was indexed, not what the test was.
_INDEXING = ("id", "record_manifest", "indexed_at", "indexed_by", "db_login", "first_indexing")


def _same_test(stored: dict[str, Any], row: dict[str, Any]) -> bool:
    """Whether ``row`` indexes the record ``stored`` indexed: the same record.json (its hash), or for a row kept
    before the history held hashes (or a folder without record.json) the same values."""
    if stored.get("record_sha256") and row.get("record_sha256"):
        return bool(stored["record_sha256"] == row["record_sha256"])
    return all(stored.get(key) == value for key, value in row.items()
               if key not in _INDEXING and key != "record_sha256" and stored.get(key) is not None)


def _simulated(simulated: bool) -> sa.ColumnElement[bool]:
    """Tests on the simulated rig (True), or on a rig (False: rows that do not say count as a rig's)."""
    return tests.c.simulated.is_(True) if simulated else sa.or_(tests.c.simulated.is_(None),
                                                                   tests.c.simulated.is_(False))


def _withdrawn(target: str) -> sa.Select[Any]:
    """The ids of ``target``'s rows that a withdrawal names."""
    return sa.select(amendments.c.target_id).where(amendments.c.target == target, amendments.c.action == "withdraw")


def _withdrawn_keys() -> sa.Select[Any]:
    """The keys of the tests withdrawn: a withdrawal names a row, and withdraws its test wherever it was indexed."""
    # never a NULL among them: 'NOT IN' a list holding NULL would hide every test
    return sa.select(tests.c.test_key).where(tests.c.id.in_(_withdrawn("tests")), tests.c.test_key.is_not(None))


def _shown(row: dict[str, Any]) -> dict[str, Any]:
    """A stored row as the commands show it (the chain's hashes are for ``--verify``)."""
    return {key: value for key, value in row.items() if key not in ("prev_hash", "row_hash")}


def _typed(table: sa.Table, row: dict[str, Any]) -> dict[str, Any]:
    """``row``'s values as the database gives them back (so that the hash computed before the row is stored is the
    one computed from it when read): a float column's number a float, NaN (which SQLite stores as nothing) None."""
    typed: dict[str, Any] = {}
    for key, value in row.items():
        kind = table.c[key].type
        if value is None:
            typed[key] = None
        elif isinstance(kind, sa.Float):
            number = float(value) + 0.0  # -0.0 is stored as 0
            typed[key] = None if math.isnan(number) else number
        elif isinstance(kind, sa.Boolean):
            typed[key] = bool(value)
        elif isinstance(kind, sa.Integer):
            typed[key] = int(value)
        else:
            typed[key] = _text(value)
    return typed


#: SQLite files whose chain this process has checked: (path, device, inode) -> table -> (the last id checked, each
#: chain's last hash), so that a later opening checks only the rows added since
_CHECKED: dict[tuple[str, int, int], dict[str, tuple[int, dict[str, str]]]] = {}


def _anchors(conn: sa.Connection, table: str, station: str | None) -> dict[str, dict[str, Any]]:
    """Each chain's anchor of ``table`` (its newest: a revision anchors once), by chain (of one station if given)."""
    query = sa.select(chain_anchors).where(chain_anchors.c.tbl == table)
    if station is not None:
        query = query.where(chain_anchors.c.chain == station)
    return {r.chain: dict(r._mapping) for r in conn.execute(query.order_by(chain_anchors.c.id))}


#: A row ``t``'s content as PostgreSQL hashes it (revision 0006's trigger): jsonb, empty values and the chain left out.
_PG_CANONICAL = "(jsonb_strip_nulls(to_jsonb(t)) - 'prev_hash' - 'row_hash')::text"


def _pg_row_hash(table: str) -> str:
    """The SQL of row ``t``'s hash recomputed by PostgreSQL, as its trigger computed it."""
    return (f"encode(sha256(convert_to(coalesce(t.prev_hash, '') || '|{table}|' || {_PG_CANONICAL}, 'UTF8')), "
            "'hex')")


def _pg_recomputed(conn: sa.Connection, table: str, anchors: dict[str, dict[str, Any]]
                   ) -> tuple[dict[int, str], dict[str, str]]:
    """Each chained row's hash and each anchored chain's digest as PostgreSQL computes them (revision 0006's
    trigger and anchors): the same canonical form as when they were written."""
    rows = conn.execute(sa.text(f"SELECT t.id, {_pg_row_hash(table)} FROM {table} t WHERE t.row_hash IS NOT NULL"))
    recomputed = {int(r[0]): str(r[1]) for r in rows}
    chain = f"coalesce(t.{CHAIN_COLUMN[table]}, '')"
    legacy: dict[str, str] = {}
    for name, anchor in anchors.items():
        digest = conn.execute(sa.text(
            f"SELECT encode(sha256(convert_to(string_agg({_PG_CANONICAL}, E'\\n' ORDER BY t.id), 'UTF8')), 'hex') "
            f"FROM {table} t WHERE t.row_hash IS NULL AND t.id <= :last AND {chain} = :chain"),
            {"last": anchor["last_id"], "chain": name}).scalar()
        legacy[name] = str(digest or "")
    return recomputed, legacy


def _print_warning(problem: str) -> None:
    print(f"warning: {problem}", file=sys.stderr)


def audit_events(test_rows: list[TestRow], teardown_rows: list[TeardownRow],
                 amendment_rows: Sequence[sa.Row[Any]]) -> list[AuditEvent]:
    """The audit trail of one valve from its rows (:meth:`HistoryStore.audit`), in the order written."""
    events: list[tuple[tuple[int, int], AuditEvent]] = []  # (the order of rows written at once, the event)
    seen: set[str] = set()
    for t in test_rows:
        key = t.test_key or t.record_dir
        again = key in seen
        seen.add(key)
        events.append(((0, t.id), AuditEvent(
            when=t.indexed_at or t.started_at,
            event="record changed after its first indexing (the first stands)" if again else "test indexed",
            id=t.id, what=f"{t.verdict}, tested {local_text(t.started_at)}, {t.record_dir}",
            by=t.indexed_by or t.operator, db_login=t.db_login, chain_hash=t.row_hash)))
    for f in teardown_rows:
        corrects = f" (corrects finding {f.corrects_id})" if f.corrects_id is not None else ""
        events.append(((1, f.id), AuditEvent(
            when=f.recorded_at, event="finding recorded", id=f.id,
            what=f"{f.finding}, opened {local_text(f.labelled_at)} by {f.labelled_by}{corrects}",
            by=f.recorded_by or f.labelled_by, db_login=f.db_login, chain_hash=f.row_hash)))
    for a in amendment_rows:
        kind = "test" if a.target == "tests" else "finding"
        events.append(((2, a.id), AuditEvent(when=a.amended_at, event=f"{kind} {a.target_id} withdrawn", id=a.id,
                                             what=a.reason, by=a.amended_by, db_login=a.db_login,
                                             chain_hash=a.row_hash)))
    events.sort(key=lambda e: (e[1].when, e[0]))
    return [event for _, event in events]


def _now() -> str:
    return dt.datetime.now(dt.UTC).isoformat(timespec="seconds")


def _login_name() -> str:
    """Who runs this program (the operating system's login name), for rows whose person was not given."""
    import getpass

    try:
        return getpass.getuser()
    except (KeyError, OSError):  # a container's user with no name
        return "unknown"


def _sqlite_pragmas(dbapi_connection: Any, _record: Any) -> None:
    cursor = dbapi_connection.cursor()
    cursor.execute("PRAGMA journal_mode=WAL")  # readers and one writer at once; a crash leaves no torn write
    cursor.execute("PRAGMA busy_timeout=30000")  # a second writer waits instead of failing
    cursor.execute("PRAGMA synchronous=NORMAL")
    cursor.close()


#: What a spreadsheet reads as the start of a formula in a cell (OWASP's list for CSV injection).
_FORMULA_STARTS = ("=", "+", "-", "@", "\t", "\r")


def _cell(value: Any) -> Any:
    """A text that a spreadsheet would run as a formula (a valve id '=HYPERLINK(...)') quoted with a leading "'",
    which spreadsheets show as text; numbers and other text as they are."""
    return "'" + value if isinstance(value, str) and value.startswith(_FORMULA_STARTS) else value


def write_csv(rows: Iterable[TestRow], handle: IO[str], columns: Sequence[str] = COLUMNS) -> int:
    """Rows as CSV with a header; returns the number of rows written.

    Text that a spreadsheet would take for a formula is written with a leading "'" (CSV injection: the ids and
    notes are typed at the bench); numbers are written as they are.
    """
    writer = csv.DictWriter(handle, fieldnames=list(columns), extrasaction="ignore")
    writer.writeheader()
    count = 0
    for row in rows:
        writer.writerow({name: _cell(value) for name, value in row.columns().items()})
        count += 1
    return count


def index_record_dir(folder: Path, url: str | None = None) -> None:
    """Add one record folder to the history (used after each test)."""
    from edc_bench.records.reader import load_record

    record = load_record(folder)
    with HistoryStore(url) as store:
        store.add(record, folder, indexed_by=record.identity.operator or None)
