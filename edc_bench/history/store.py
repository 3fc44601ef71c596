"""The station's test history: one row per record folder, in SQLite or PostgreSQL.

SQLAlchemy Core speaks to both. SQLite (the default, in the station's data
folder) runs in WAL mode with a busy timeout, so two tests finishing at
once both land and readers never block writers; a shop shares one history
by giving every station the same PostgreSQL URL. Each record is added in
one transaction keyed by its folder, so adding it twice changes nothing and
a writer killed half-way leaves no partial row.

The records stay the source of truth for tests: the tests table is an
index, and ``edc-bench history --add FOLDER...`` rebuilds it from them.
Teardown findings (``edc-bench label``) live only here: what the shop found
when it opened a valve, the label the classifier can learn from. A teardown
labels the valve's last trustworthy test before it (:meth:`HistoryStore.labelled_tests`).
"""

from __future__ import annotations

import csv
import datetime as dt
import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import IO, TYPE_CHECKING, Any

import sqlalchemy as sa

from edc_bench.errors import ConfigError
from edc_bench.history.url import check_url, default_url
from edc_bench.verdict.verdicts import Verdict

if TYPE_CHECKING:
    from edc_bench.records.schema import Record

metadata = sa.MetaData()

tests = sa.Table(
    "tests", metadata,
    sa.Column("id", sa.Integer, primary_key=True, autoincrement=True),
    sa.Column("record_dir", sa.String(1024), nullable=False, unique=True),
    sa.Column("started_at", sa.String(40), nullable=False, index=True),
    sa.Column("valve_id", sa.String(200), nullable=False, index=True),
    sa.Column("pump_serial", sa.String(200), nullable=False, index=True),
    sa.Column("variant", sa.String(200), nullable=False),
    sa.Column("part_number", sa.String(100), nullable=False),
    sa.Column("verdict", sa.String(20), nullable=False),
    sa.Column("af_v", sa.Float),
    sa.Column("a1_v_s_per_mm", sa.Float),
    sa.Column("af_rel", sa.Float),
    sa.Column("a1_rel", sa.Float),
    sa.Column("probability_faulty", sa.Float),
    sa.Column("distance", sa.Float),
    sa.Column("station", sa.String(200), nullable=False),
    sa.Column("operator", sa.String(200), nullable=False),
    sa.Column("clock", sa.String(20), nullable=False),
    sa.Column("software_version", sa.String(40), nullable=False),
    sa.Column("reason", sa.Text, nullable=False),
    sa.Column("model_name", sa.String(200)),  # the classifier that judged (None: not classified)
    sa.Column("model_sha256", sa.String(64)),
    # how the test went: the coil (referred to 20 degC; in its spec?), whether the model fitted the pump, when and
    # why it stopped (None in rows of an older edc-bench, and where the record does not say)
    sa.Column("coil_r20_ohm", sa.Float),
    sa.Column("coil_in_spec", sa.Boolean),
    sa.Column("model_fits", sa.Boolean),
    sa.Column("stop_reason", sa.String(40)),
    sa.Column("test_s", sa.Float),
)

teardowns = sa.Table(
    "teardowns", metadata,
    sa.Column("id", sa.Integer, primary_key=True, autoincrement=True),
    sa.Column("valve_id", sa.String(200), nullable=False, index=True),
    sa.Column("finding", sa.String(20), nullable=False),
    sa.Column("clearance_mm", sa.Float),
    sa.Column("note", sa.Text, nullable=False),
    sa.Column("labelled_by", sa.String(200), nullable=False),
    sa.Column("labelled_at", sa.String(40), nullable=False),  # ISO date or date-time (UTC) of the teardown
    sa.Column("recorded_at", sa.String(40), nullable=False),
)

#: Teardown findings and the class each teaches the classifier (1: the valve must be replaced).
FINDINGS: dict[str, int] = {"reusable": 0, "worn": 1, "faulty": 1}

#: Teardown columns in listings, in order (the id: to delete a finding recorded by mistake).
TEARDOWN_COLUMNS = tuple(c.name for c in teardowns.columns)

#: Columns in listings and CSV exports, in order.
COLUMNS = tuple(c.name for c in tests.columns if c.name != "id")


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
    }


@dataclass(frozen=True)
class Filters:
    """What to list: every given field must match (valve and serial exactly, dates as ISO prefixes)."""

    valve_id: str | None = None
    pump_serial: str | None = None
    variant: str | None = None
    verdict: str | None = None
    since: str | None = None
    until: str | None = None


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
    """

    def __init__(self, url: str | None = None, must_exist: bool = False) -> None:
        check_url(url, must_exist)
        self.url = url or default_url()
        parsed = sa.engine.make_url(self.url)
        self.is_sqlite = parsed.get_backend_name() == "sqlite"
        kwargs: dict[str, Any] = {}
        if self.is_sqlite:
            kwargs["connect_args"] = {"timeout": 30.0}
        try:
            self.engine = sa.create_engine(parsed, **kwargs)
        except (sa.exc.ArgumentError, ImportError, sa.exc.NoSuchModuleError) as exc:
            raise ConfigError(f"history database {self.url!r}: {exc} (PostgreSQL needs edc-bench[postgres])") from None
        if self.is_sqlite:
            sa.event.listen(self.engine, "connect", _sqlite_pragmas)
        self._create_tables()

    def _create_tables(self) -> None:
        # Two stations (or two tests) opening a new database at once may both try to create
        # the table; the loser sees "already exists" and simply finds it on the next look.
        for attempt in range(3):
            try:
                metadata.create_all(self.engine)
                self._add_missing_columns()
                return
            except (sa.exc.OperationalError, sa.exc.ProgrammingError, sa.exc.IntegrityError) as exc:
                # ... or both add a new column to an older history ("duplicate column" in SQLite's words)
                if ("already exists" in str(exc.orig) or "duplicate column" in str(exc.orig)) and attempt < 2:
                    continue
                raise ConfigError(f"history database {self.url!r} cannot be opened: {exc.orig}") from None

    def _add_missing_columns(self) -> None:
        """Bring a history made by an older edc-bench up to date: columns added since are added (empty)."""
        inspector = sa.inspect(self.engine)
        for table in (tests, teardowns):
            present = {c["name"] for c in inspector.get_columns(table.name)}
            for column in table.columns:
                if column.name not in present:
                    kind = column.type.compile(dialect=self.engine.dialect)
                    with self.engine.begin() as conn:
                        conn.execute(sa.text(f'ALTER TABLE {table.name} ADD COLUMN "{column.name}" {kind}'))

    def close(self) -> None:
        """Release connections."""
        self.engine.dispose()

    def __enter__(self) -> HistoryStore:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def add(self, record: Record, record_dir: Path) -> bool:
        """Index one record folder (again: its row is replaced). True if the folder was not indexed before."""
        return self.add_row(row_from_record(record, record_dir))

    def add_row(self, row: dict[str, Any]) -> bool:
        """Store one test's row (:func:`row_from_record`), replacing a row of the same ``record_dir``; True if there
        was none."""
        with self.engine.begin() as conn:  # one transaction: all of the row or nothing
            replaced = conn.execute(tests.delete().where(tests.c.record_dir == row["record_dir"])).rowcount
            conn.execute(tests.insert().values(**row))
        return not replaced

    def list(self, filters: Filters = Filters(), limit: int | None = None) -> list[dict[str, Any]]:
        """Rows matching ``filters``, oldest first (the newest ``limit`` if given)."""
        query = sa.select(*(tests.c[name] for name in COLUMNS))
        f = filters
        for column, value in ((tests.c.valve_id, f.valve_id), (tests.c.pump_serial, f.pump_serial),
                              (tests.c.verdict, f.verdict)):
            if value is not None:
                query = query.where(column == value)
        if f.variant is not None:
            query = query.where(sa.or_(tests.c.variant == f.variant, tests.c.part_number == f.variant))
        if f.since is not None:
            query = query.where(tests.c.started_at >= f.since)
        if f.until is not None:
            # a day given alone includes the whole day
            bound = f.until if "T" in f.until else f.until + "T99"
            query = query.where(tests.c.started_at <= bound)
        query = query.order_by(tests.c.started_at.desc(), tests.c.id.desc())
        if limit is not None:
            query = query.limit(limit)
        with self.engine.connect() as conn:
            rows = [dict(r._mapping) for r in conn.execute(query)]
        return rows[::-1]

    def add_teardown(self, valve_id: str, finding: str, *, labelled_by: str, labelled_at: str,
                     clearance_mm: float | None = None, note: str = "") -> dict[str, Any]:
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
        """
        if finding not in FINDINGS:
            raise ConfigError(f"teardown finding {finding!r}: use one of {', '.join(FINDINGS)}")
        row = {"valve_id": valve_id, "finding": finding, "clearance_mm": clearance_mm, "note": note,
               "labelled_by": labelled_by, "labelled_at": labelled_at,
               "recorded_at": dt.datetime.now(dt.UTC).isoformat(timespec="seconds")}
        with self.engine.begin() as conn:
            conn.execute(teardowns.insert().values(**row))
        return row

    def delete_teardown(self, teardown_id: int) -> dict[str, Any]:
        """Remove a finding recorded by mistake; returns it."""
        with self.engine.begin() as conn:
            found = conn.execute(sa.select(teardowns).where(teardowns.c.id == teardown_id)).first()
            if found is None:
                raise ConfigError(f"no teardown finding with id {teardown_id} (see 'edc-bench label --list')")
            conn.execute(teardowns.delete().where(teardowns.c.id == teardown_id))
        return dict(found._mapping)

    def teardowns(self, valve_id: str | None = None) -> list[dict[str, Any]]:
        """Teardown findings (of one valve if given), in the order of the teardowns."""
        query = sa.select(*(teardowns.c[name] for name in TEARDOWN_COLUMNS))
        if valve_id is not None:
            query = query.where(teardowns.c.valve_id == valve_id)
        query = query.order_by(teardowns.c.labelled_at, teardowns.c.id)
        with self.engine.connect() as conn:
            return [dict(r._mapping) for r in conn.execute(query)]

    def labelled_tests(self) -> list[dict[str, Any]]:
        """Every teardown with the test it labels, oldest first.

        A teardown labels the valve's last test before it that was judged on
        its features (not INVALID, relative features known): the valve as the
        bench last saw it; a teardown given as a date alone counts that whole
        day. Each test is labelled once: a second teardown of the valve labels
        only a test after the first. Each row is the test's history row plus
        ``finding``, ``label`` (1: replace), ``teardown_clearance_mm``,
        ``labelled_by`` and ``labelled_at``; teardowns with no such test are
        left out (:meth:`unmatched_teardowns` lists them).
        """
        return [row for row in self.teardown_matches() if row.get("record_dir")]

    def unmatched_teardowns(self) -> list[dict[str, Any]]:
        """Teardowns of valves with no test judged before them (nothing to learn from yet)."""
        return [row for row in self.teardown_matches() if not row.get("record_dir")]

    def teardown_matches(self) -> list[dict[str, Any]]:
        """Every teardown in order, with the test it labels (:meth:`labelled_tests`) or only its valve if none."""
        found = self.teardowns()
        valves = sorted({t["valve_id"] for t in found})
        query = sa.select(*(tests.c[name] for name in COLUMNS)).where(
            tests.c.valve_id.in_(valves), tests.c.af_rel.is_not(None), tests.c.a1_rel.is_not(None),
            tests.c.verdict != Verdict.INVALID).order_by(tests.c.started_at, tests.c.id)
        by_valve: dict[str, list[dict[str, Any]]] = {}
        if valves:
            with self.engine.connect() as conn:
                for r in conn.execute(query):
                    by_valve.setdefault(r.valve_id, []).append(dict(r._mapping))
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

    def trend(self, valve_id: str) -> list[dict[str, Any]]:
        """Every trustworthy visit of one valve, oldest first."""
        return [r for r in self.list(Filters(valve_id=valve_id)) if r["verdict"] != Verdict.INVALID]


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
        store.add(record, folder)
