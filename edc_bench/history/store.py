"""The station's test history, in SQLite or PostgreSQL: tests as indexed, teardown findings, withdrawals, adoptions.

SQLAlchemy Core speaks to both. SQLite (the default, in the station's data
folder) runs in WAL mode with a busy timeout, so two tests finishing at
once both land and readers never block writers; a shop shares one history
by giving every station the same PostgreSQL URL (docs/shop-network.md).
Each row is written in one transaction, so a writer killed half-way leaves
no partial row.

Nothing stored is changed or deleted (:mod:`edc_bench.history.schema`): a
record folder indexed again with other content is a new row, a withdrawal
or a corrected finding is a row naming the row it concerns. Readers show
the current state; :meth:`HistoryStore.audit` the whole chain.

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
from collections.abc import Callable, Iterable, Sequence
from contextlib import AbstractContextManager
from dataclasses import dataclass
from pathlib import Path
from typing import IO, TYPE_CHECKING, Any

import sqlalchemy as sa

from edc_bench.errors import ConfigError
from edc_bench.history import migrate
from edc_bench.history.guard import database_errors
from edc_bench.history.schema import (
    COLUMNS,
    TEARDOWN_COLUMNS,
    adoptions,
    amendments,
    reference_valves,
    rig_checks,
    teardowns,
    tests,
)
from edc_bench.history.secrets import redact, secrets_of, shown_url
from edc_bench.history.url import check_url, default_url
from edc_bench.records.integrity import file_digest
from edc_bench.records.writer import RECORD_FILE
from edc_bench.verdict.verdicts import Verdict

if TYPE_CHECKING:
    from edc_bench.records.schema import Record

#: Teardown findings and the class each teaches the classifier (1: the valve must be replaced).
FINDINGS: dict[str, int] = {"reusable": 0, "worn": 1, "faulty": 1}


def _text(value: Any) -> str:
    """``value`` as text any database stores: text that is not valid Unicode (a hand-edited record) escaped."""
    return str(value).encode("utf-8", "backslashreplace").decode("utf-8")


def _finite(value: float | None) -> float | None:
    return value if value is not None and math.isfinite(value) else None


def row_from_record(record: Record, record_dir: Path) -> dict[str, Any]:
    """The history row of a record (record.json's content, typed)."""
    cls, identity, coil, stop = record.classification, record.identity, record.coil, record.stop
    rel = cls.features_rel if cls is not None else {}
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
        "af_v": _finite(record.features.get("af")),
        "a1_v_s_per_mm": _finite(record.features.get("a1")),
        "af_rel": _finite(rel.get("af")),
        "a1_rel": _finite(rel.get("a1")),
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
        "decision": None if record.retest is None else _text(record.retest.decision)[:20] or None,
    }


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


def parse_day(text: str | None, name: str) -> str | None:
    """An ISO date (``2026-11-22``) or date-time, checked; None stays None."""
    if text is None:
        return None
    try:
        return dt.datetime.fromisoformat(text).isoformat() if "T" in text else dt.date.fromisoformat(text).isoformat()
    except ValueError:
        raise ConfigError(f"{name} {text!r} is not a date: write it as YYYY-MM-DD (or YYYY-MM-DDTHH:MM)") from None


class HistoryStore:
    """The history database.

    Parameters
    ----------
    url : str, optional
        SQLAlchemy URL: ``sqlite:///path`` or ``postgresql+psycopg://user@host/db``
        (default: :func:`default_url`).
    must_exist : bool, optional
        Refuse a SQLite file named by the URL that does not exist (see :func:`check_url`).

    A station's SQLite file is brought to this edc-bench's schema revision when opened; a PostgreSQL history must
    be at it already (its owner runs ``edc-bench history --upgrade``).
    """

    def __init__(self, url: str | None = None, must_exist: bool = False) -> None:
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
        try:
            self.engine = sa.create_engine(parsed, **kwargs)
        except (sa.exc.ArgumentError, ImportError, sa.exc.NoSuchModuleError) as exc:
            raise ConfigError(redact(f"history database {self.shown_url!r}: {exc} (PostgreSQL needs "
                                     "edc-bench[postgres])", self._secrets)) from None
        if self.is_sqlite:
            sa.event.listen(self.engine, "connect", _sqlite_pragmas)
        #: the database login writing rows (PostgreSQL), None on SQLite
        self.login: str | None = None
        with self._guard("read"):
            with self.engine.connect() as conn:
                revision = migrate.current(conn)
                if not self.is_sqlite:
                    self.login = conn.execute(sa.text("SELECT current_user")).scalar()
            if revision == migrate.head():
                return
            if self.is_sqlite and (revision is None or migrate.is_known(revision)):
                migrate.upgrade(self.engine)  # a station's own file: brought up to date as it is opened
                return
            with self.engine.connect() as conn:
                migrate.require_head(conn, self.shown_url)

    def _guard(self, action: str) -> AbstractContextManager[None]:
        """Database errors as one line a person can act on: a refused right names whose login has it."""
        return database_errors(action, self.shown_url, self._secrets, self.login)

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
        """Store one test's row (:func:`row_from_record`); see :meth:`add`."""
        row = {**row, "indexed_at": _now(), "indexed_by": indexed_by or _login_name(), "db_login": self.login}
        with self._guard("add-test"), self.engine.begin() as conn:  # one transaction: all of the row or nothing
            before = conn.execute(sa.select(tests).where(tests.c.record_dir == row["record_dir"])
                                  .order_by(tests.c.id.desc()).limit(1)).first()
            if before is not None:
                if conn.execute(sa.select(tests.c.id).where(tests.c.record_dir == row["record_dir"],
                                                            tests.c.id.in_(_withdrawn("tests")))).first():
                    return "withdrawn"
                if _same_test(dict(before._mapping), row):
                    return "unchanged"
            conn.execute(tests.insert().values(**row))
        return "new" if before is None else "changed"

    def _current_tests(self) -> sa.ColumnElement[bool]:
        """The rows that are tests as they stand: each folder's newest row, unless the test was withdrawn."""
        newest = sa.select(sa.func.max(tests.c.id)).group_by(tests.c.record_dir)
        withdrawn = sa.select(tests.c.record_dir).where(tests.c.id.in_(_withdrawn("tests")))
        return sa.and_(tests.c.id.in_(newest), tests.c.record_dir.not_in(withdrawn))

    def list(self, filters: Filters = Filters(), limit: int | None = None) -> list[dict[str, Any]]:
        """Tests as they stand matching ``filters``, oldest first (the newest ``limit`` if given)."""
        query = sa.select(*(tests.c[name] for name in COLUMNS)).where(self._current_tests())
        f = filters
        for column, value in ((tests.c.valve_id, f.valve_id), (tests.c.pump_serial, f.pump_serial),
                              (tests.c.verdict, f.verdict)):
            if value is not None:
                query = query.where(column == value)
        if f.variant is not None:
            query = query.where(sa.or_(tests.c.variant == f.variant, tests.c.part_number == f.variant))
        if f.simulated is not None:
            query = query.where(_simulated(f.simulated))
        if f.since is not None:
            query = query.where(tests.c.started_at >= f.since)
        if f.until is not None:
            # a day given alone includes the whole day
            bound = f.until if "T" in f.until else f.until + "T99"
            query = query.where(tests.c.started_at <= bound)
        query = query.order_by(tests.c.started_at.desc(), tests.c.id.desc())
        if limit is not None:
            query = query.limit(limit)
        return self._rows(query)[::-1]

    def indexed(self) -> list[dict[str, Any]]:
        """Every test as it stands with how it was indexed (record hash and manifest), for ``--verify``."""
        return self._rows(sa.select(tests).where(self._current_tests()).order_by(tests.c.id))

    def withdraw_test(self, test_id: int, reason: str, by: str | None = None) -> dict[str, Any]:
        """Withdraw a test (its id from ``history``): it leaves listings, trends and training; ``--audit`` keeps it.
        Returns the test's row."""
        with self._guard("withdraw"), self.engine.begin() as conn:
            found = conn.execute(sa.select(tests).where(tests.c.id == test_id)).first()
            if found is None:
                raise ConfigError(f"no test with id {test_id} in {self.shown_url} (see 'edc-bench history')")
            if conn.execute(sa.select(amendments.c.id).where(
                    amendments.c.target == "tests",
                    amendments.c.target_id.in_(sa.select(tests.c.id).where(
                        tests.c.record_dir == found.record_dir)))).first() is not None:
                raise ConfigError(f"test {test_id} (valve {found.valve_id!r}) is withdrawn already "
                                  f"(see 'edc-bench history --audit {found.valve_id}')")
            conn.execute(amendments.insert().values(target="tests", target_id=test_id, action="withdraw",
                                                    reason=reason, amended_by=by or _login_name(), amended_at=_now(),
                                                    db_login=self.login))
        return dict(found._mapping)

    # -- teardowns ---------------------------------------------------------------------------------------------

    def add_teardown(self, valve_id: str, finding: str, *, labelled_by: str, labelled_at: str,
                     clearance_mm: float | None = None, note: str = "", corrects: int | None = None) -> dict[str, Any]:
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
               "corrects_id": corrects, "db_login": self.login}
        with self._guard("label"), self.engine.begin() as conn:
            if corrects is not None:
                self._current_teardown(conn, corrects, valve_id)
            row["id"] = conn.execute(teardowns.insert().values(**row)).inserted_primary_key[0]
        return row

    def _current_teardown(self, conn: sa.Connection, teardown_id: int, valve_id: str | None = None) -> Any:
        """The finding ``teardown_id`` if it stands (not withdrawn nor corrected); a ConfigError saying why not."""
        found = conn.execute(sa.select(teardowns).where(teardowns.c.id == teardown_id)).first()
        if found is None or (valve_id is not None and found.valve_id != valve_id):
            of = f" of valve {valve_id!r}" if valve_id is not None else ""
            raise ConfigError(f"no teardown finding with id {teardown_id}{of} (see 'edc-bench label --list')")
        if teardown_id not in {r["id"] for r in self._standing_teardowns(conn)}:
            raise ConfigError(f"teardown finding {teardown_id} is withdrawn or corrected already (see 'edc-bench "
                              f"history --audit {found.valve_id}')")
        return found

    def withdraw_teardown(self, teardown_id: int, reason: str, by: str | None = None) -> dict[str, Any]:
        """Withdraw a finding recorded by mistake (its id from ``label --list``); returns it."""
        with self._guard("withdraw"), self.engine.begin() as conn:
            found = self._current_teardown(conn, teardown_id)
            conn.execute(amendments.insert().values(target="teardowns", target_id=teardown_id, action="withdraw",
                                                    reason=reason, amended_by=by or _login_name(), amended_at=_now(),
                                                    db_login=self.login))
        return dict(found._mapping)

    def _standing_teardowns(self, conn: sa.Connection, valve_id: str | None = None) -> list[dict[str, Any]]:
        query = sa.select(*(teardowns.c[name] for name in TEARDOWN_COLUMNS))
        if valve_id is not None:
            query = query.where(teardowns.c.valve_id == valve_id)
        rows = [dict(r._mapping) for r in conn.execute(query.order_by(teardowns.c.labelled_at, teardowns.c.id))]
        withdrawn = {r[0] for r in conn.execute(_withdrawn("teardowns"))}
        every = rows if valve_id is None else [dict(r._mapping) for r in conn.execute(
            sa.select(teardowns.c.id, teardowns.c.corrects_id))]
        corrected = {r["corrects_id"] for r in every if r["corrects_id"] is not None and r["id"] not in withdrawn}
        return [r for r in rows if r["id"] not in withdrawn and r["id"] not in corrected]

    def teardowns(self, valve_id: str | None = None) -> list[dict[str, Any]]:
        """Teardown findings as they stand (of one valve if given), in the order of the teardowns."""
        with self._guard("read"), self.engine.connect() as conn:
            return self._standing_teardowns(conn, valve_id)

    def labelled_tests(self, include_simulated: bool = False) -> list[dict[str, Any]]:
        """Every teardown with the test it labels, oldest first.

        A teardown labels the valve's last test before it that was judged on
        its features (not INVALID, relative features known): the valve as the
        bench last saw it; a teardown given as a date alone counts that whole
        day. Each test is labelled once: a second teardown of the valve labels
        only a test after the first. Each row is the test's history row plus
        ``finding``, ``label`` (1: replace), ``teardown_clearance_mm``,
        ``labelled_by`` and ``labelled_at``; teardowns with no such test are
        left out (:meth:`unmatched_teardowns` lists them). Withdrawn tests and
        findings, and findings corrected since, count for nothing; tests on
        the simulated rig neither, unless ``include_simulated``.
        """
        return [row for row in self.teardown_matches(include_simulated) if row.get("record_dir")]

    def unmatched_teardowns(self, include_simulated: bool = False) -> list[dict[str, Any]]:
        """Teardowns of valves with no test judged before them (nothing to learn from yet)."""
        return [row for row in self.teardown_matches(include_simulated) if not row.get("record_dir")]

    def teardown_matches(self, include_simulated: bool = False) -> list[dict[str, Any]]:
        """Every teardown in order, with the test it labels (:meth:`labelled_tests`) or only its valve if none."""
        found = self.teardowns()
        valves = sorted({t["valve_id"] for t in found})
        query = sa.select(*(tests.c[name] for name in COLUMNS)).where(
            self._current_tests(), tests.c.valve_id.in_(valves), tests.c.af_rel.is_not(None),
            tests.c.a1_rel.is_not(None), tests.c.verdict != Verdict.INVALID).order_by(tests.c.started_at, tests.c.id)
        if not include_simulated:
            query = query.where(_simulated(False))
        by_valve: dict[str, list[dict[str, Any]]] = {}
        for test in (self._rows(query) if valves else []):
            by_valve.setdefault(test["valve_id"], []).append(test)
        rows = []
        previous: dict[str, str] = {}  # valve -> bound of its previous teardown
        for teardown in found:
            valve = teardown["valve_id"]
            # a date alone counts the whole day: the valve tested in the morning and opened in the afternoon
            bound = teardown["labelled_at"] if "T" in teardown["labelled_at"] else teardown["labelled_at"] + "T99"
            # a test labels once: the test after the valve's previous teardown and before this one
            after = previous.get(valve, "")
            between = [t for t in by_valve.get(valve, []) if after < t["started_at"] <= bound]
            previous[valve] = bound
            test = between[-1] if between else {"valve_id": valve}
            rows.append({**test, "teardown_id": teardown["id"], "finding": teardown["finding"],
                         "label": FINDINGS[teardown["finding"]], "teardown_clearance_mm": teardown["clearance_mm"],
                         "labelled_by": teardown["labelled_by"], "labelled_at": teardown["labelled_at"],
                         "note": teardown["note"]})
        return rows

    def trend(self, valve_id: str, include_simulated: bool = False) -> list[dict[str, Any]]:
        """Every trustworthy visit of one valve, oldest first (on a rig; the simulated rig's too if asked)."""
        filters = Filters(valve_id=valve_id, simulated=None if include_simulated else False)
        return [r for r in self.list(filters) if r["verdict"] != Verdict.INVALID]

    # -- the whole chain ---------------------------------------------------------------------------------------

    def audit(self, valve_id: str) -> list[dict[str, Any]]:
        """Everything the history holds of one valve, in the order it was written: each indexing of its tests,
        each finding, each correction and withdrawal, with who and when (``when``, ``event``, ``id``, ``what``,
        ``by``, ``db_login``)."""
        with self._guard("read"), self.engine.connect() as conn:
            rows = [dict(r._mapping) for r in conn.execute(
                sa.select(tests).where(tests.c.valve_id == valve_id).order_by(tests.c.id))]
            found = [dict(r._mapping) for r in conn.execute(
                sa.select(teardowns).where(teardowns.c.valve_id == valve_id).order_by(teardowns.c.id))]
            changes = [dict(r._mapping) for r in conn.execute(sa.select(amendments).where(sa.or_(
                sa.and_(amendments.c.target == "tests", amendments.c.target_id.in_([r["id"] for r in rows])),
                sa.and_(amendments.c.target == "teardowns", amendments.c.target_id.in_([t["id"] for t in found])),
            )).order_by(amendments.c.id))]
        return audit_events(rows, found, changes)

    def add_adoption(self, model_name: str, model_sha256: str, station: str, adopted_by: str,
                     then: Callable[[], object] | None = None) -> dict[str, Any]:
        """Record that ``station`` now judges with a model (``edc-bench train --adopt``); returns the row.

        ``then`` (the station's own change) runs after the row is written and before it is committed: a login that
        may not adopt is refused before the station changes, and a station change that fails leaves no row.
        """
        row = {"station": station, "model_name": model_name, "model_sha256": model_sha256, "adopted_by": adopted_by,
               "adopted_at": _now(), "db_login": self.login}
        with self._guard("adopt"), self.engine.begin() as conn:
            conn.execute(adoptions.insert().values(**row))
            if then is not None:
                then()
        return row

    # -- the rig self-check's ledger ----------------------------------------------------------------------------

    def add_reference(self, row: dict[str, Any]) -> dict[str, Any]:
        """Register a station's reference valve (``edc-bench rig-selfcheck --register``); returns the stored row.

        ``row`` holds the columns of :data:`~edc_bench.history.schema.reference_valves` but ``id``,
        ``registered_at`` and ``db_login``. A registration again is a new row: the station's newest stands, the
        earlier ones stay (and the checks made against them).
        """
        row = {**row, "registered_at": _now(), "db_login": self.login}
        with self._guard("register-reference"), self.engine.begin() as conn:
            row["id"] = conn.execute(reference_valves.insert().values(**row)).inserted_primary_key[0]
        return row

    def reference(self, station: str) -> dict[str, Any] | None:
        """The station's reference valve as it stands (its newest registration), or None if it has none."""
        query = (sa.select(reference_valves).where(reference_valves.c.station == station)
                 .order_by(reference_valves.c.id.desc()).limit(1))
        found = self._rows(query)
        return found[0] if found else None

    def add_rig_check(self, row: dict[str, Any]) -> dict[str, Any]:
        """Store one rig self-check; returns the stored row (columns of :data:`~edc_bench.history.schema.rig_checks`
        but ``id``, ``checked_at`` and ``db_login``)."""
        row = {**row, "checked_at": _now(), "db_login": self.login}
        with self._guard("add-rig-check"), self.engine.begin() as conn:
            row["id"] = conn.execute(rig_checks.insert().values(**row)).inserted_primary_key[0]
        return row

    def rig_checks(self, station: str | None = None, reference_id: int | None = None) -> list[dict[str, Any]]:
        """Rig self-checks, oldest first: of one station and one registration if given."""
        query = sa.select(rig_checks)
        if station is not None:
            query = query.where(rig_checks.c.station == station)
        if reference_id is not None:
            query = query.where(rig_checks.c.reference_id == reference_id)
        return self._rows(query.order_by(rig_checks.c.id))

    def references(self, station: str | None = None) -> list[dict[str, Any]]:
        """Every registration, oldest first (of one station if given)."""
        query = sa.select(reference_valves)
        if station is not None:
            query = query.where(reference_valves.c.station == station)
        return self._rows(query.order_by(reference_valves.c.id))

    def tests_since(self, station: str, since: str) -> int:
        """Tests of ``station`` that started after ``since`` (an ISO time), withdrawn ones too: what the self-check's
        due rule counts (:func:`edc_bench.selfcheck.due.selfcheck_due`)."""
        query = sa.select(sa.func.count(sa.distinct(tests.c.record_dir))).where(
            tests.c.station == station, tests.c.started_at > since)
        with self._guard("read"), self.engine.connect() as conn:
            return int(conn.execute(query).scalar() or 0)

    def _rows(self, query: sa.Select[Any]) -> list[dict[str, Any]]:
        with self._guard("read"), self.engine.connect() as conn:
            return [dict(r._mapping) for r in conn.execute(query)]


#: The columns that say how a row was indexed, not what the test was.
_INDEXING = ("id", "record_manifest", "indexed_at", "indexed_by", "db_login")


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


def audit_events(test_rows: list[dict[str, Any]], teardown_rows: list[dict[str, Any]],
                 amendment_rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """The audit trail of one valve from its rows (:meth:`HistoryStore.audit`), in the order written."""
    events = []
    seen: set[str] = set()
    for t in test_rows:
        again = t["record_dir"] in seen
        seen.add(t["record_dir"])
        events.append({"when": t["indexed_at"] or t["started_at"], "event": "test re-indexed (record changed)"
                       if again else "test indexed", "id": t["id"],
                       "what": f"{t['verdict']}, tested {t['started_at'][:16]}, {t['record_dir']}",
                       "by": t["indexed_by"] or t["operator"], "db_login": t["db_login"], "order": (0, t["id"])})
    for f in teardown_rows:
        corrects = f" (corrects finding {f['corrects_id']})" if f["corrects_id"] is not None else ""
        events.append({"when": f["recorded_at"], "event": "finding recorded", "id": f["id"],
                       "what": f"{f['finding']}, opened {f['labelled_at'][:16]}{corrects}", "by": f["labelled_by"],
                       "db_login": f["db_login"], "order": (1, f["id"])})
    for a in amendment_rows:
        kind = "test" if a["target"] == "tests" else "finding"
        events.append({"when": a["amended_at"], "event": f"{kind} {a['target_id']} withdrawn", "id": a["id"],
                       "what": a["reason"], "by": a["amended_by"], "db_login": a["db_login"], "order": (2, a["id"])})
    events.sort(key=lambda e: (e["when"], e["order"]))
    return [{key: value for key, value in e.items() if key != "order"} for e in events]


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


def write_csv(rows: Iterable[dict[str, Any]], handle: IO[str], columns: Sequence[str] = COLUMNS) -> int:
    """Rows as CSV with a header; returns the number of rows written.

    Text that a spreadsheet would take for a formula is written with a leading "'" (CSV injection: the ids and
    notes are typed at the bench); numbers are written as they are.
    """
    writer = csv.DictWriter(handle, fieldnames=list(columns), extrasaction="ignore")
    writer.writeheader()
    count = 0
    for row in rows:
        writer.writerow({name: _cell(value) for name, value in row.items()})
        count += 1
    return count


def index_record_dir(folder: Path, url: str | None = None) -> None:
    """Add one record folder to the history (used after each test)."""
    from edc_bench.records.reader import load_record

    record = load_record(folder)
    with HistoryStore(url) as store:
        store.add(record, folder, indexed_by=record.identity.operator or None)
