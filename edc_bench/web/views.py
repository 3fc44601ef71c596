"""What the rigs, valves and models pages show, read from the history (each a bounded query: no page reads a
whole table)."""

from __future__ import annotations

import datetime as dt
import json
from dataclasses import dataclass
from typing import Any, ClassVar

import sqlalchemy as sa

from edc_bench.history.rig_ledger import COLUMNS
from edc_bench.history.rows import AdoptionRow, TestRow
from edc_bench.history.schema import adoptions, amendments, reference_valves, rig_checks, tests
from edc_bench.history.store import HistoryStore, standing_tests
from edc_bench.learning.candidate_evaluation import CandidateEvaluation
from edc_bench.timefmt import parse_stored

#: the checks a rig's chart and trend rest on: its newest (on its own page; in the chain's table, the newest
#: OVERVIEW_CHECKS: a quarter of weekly checks says where a rig is heading)
CHECKS_SHOWN = 60
OVERVIEW_CHECKS = 13
#: a search's valves and pumps listed
SEARCH_LIMIT = 50
#: the fewest measured checks a trend is drawn through
TREND_MIN_CHECKS = 3
#: Student's t at 99 % (two-sided) by degrees of freedom (2.6 beyond: near the normal's 2.58): six figures per rig
#: and a chain of rigs, so a trend is announced only where the checks leave little doubt
_T99 = {1: 63.66, 2: 9.92, 3: 5.84, 4: 4.60, 5: 4.03, 6: 3.71, 7: 3.50, 8: 3.36, 9: 3.25, 10: 3.17, 11: 3.11,
        12: 3.05, 13: 3.01, 14: 2.98, 15: 2.95, 16: 2.92, 17: 2.90, 18: 2.88, 19: 2.86, 20: 2.85, 25: 2.79, 30: 2.75,
        40: 2.70, 60: 2.66}
#: a trend that reaches its limit later than this is not announced: a service planned a year ahead is no warning
HORIZON_DAYS = 365


def _t99(dof: int) -> float:
    """Student's t at 99 % for ``dof`` degrees of freedom (the next smaller tabled one's: on the safe side)."""
    return _T99[max(d for d in _T99 if d <= dof)] if dof >= 1 else float("inf")


@dataclass(frozen=True)
class FigureDrift:
    """One figure of a station's self-checks: its drift in units of its tolerance at each check, and where its
    trend crosses a limit."""

    name: str
    label: str
    points: tuple[tuple[str, float], ...]
    slope_per_day: float | None
    #: when the trend reaches +/-1 (ISO, UTC; None: no trend, or moving away from the limits)
    crossing_at: str | None
    #: the limit the trend heads for (+1 or -1)
    limit_sign: float = 1.0


@dataclass(frozen=True)
class Reference:
    """A station's reference valve as registered."""

    valve_id: str
    variant: str
    registered_at: str
    registered_by: str


@dataclass(frozen=True)
class RigCheck:
    """One self-check (or a due one skipped): its result, what drifted, and each figure's drift against the
    registration (relative, or absolute for the two zeros; None where it was not measured)."""

    checked_at: str
    verdict: str
    causes: str
    checked_by: str
    drift: tuple[tuple[str, float | None, float | None], ...]  # (figure, drift, tolerance)

    def drift_of(self, name: str) -> float | None:
        """The figure's drift (None: not measured)."""
        return next((d for n, d, _ in self.drift if n == name), None)


@dataclass(frozen=True)
class RigHealth:
    """A station's rig: its reference valve, its checks, each figure's drift, and when service is due."""

    station: str
    reference: Reference | None
    checks: tuple[RigCheck, ...]
    skipped: int
    drifts: tuple[FigureDrift, ...]
    #: 'now' (the latest check is NO-GO), an ISO time (the first trend to cross a limit), or None
    service_due: str | None
    due_figure: str | None


@dataclass(frozen=True)
class ValveHit:
    """A valve a search found: its pump, how many tests, the latest."""

    valve_id: str
    pump: str
    tests: int
    latest: str


def _trend(points: list[tuple[dt.datetime, float]]) -> tuple[float | None, dt.datetime | None, float]:
    """The least-squares line through (time, drift/tolerance): its slope per day and when it reaches +/-1."""
    if len(points) < TREND_MIN_CHECKS:
        return None, None, 1.0
    t0 = points[0][0]
    xs = [(t - t0).total_seconds() / 86400 for t, _ in points]
    ys = [v for _, v in points]
    mean_x, mean_y = sum(xs) / len(xs), sum(ys) / len(ys)
    sxx = sum((x - mean_x) ** 2 for x in xs)
    if sxx == 0:
        return None, None, 1.0
    slope = sum((x - mean_x) * (y - mean_y) for x, y in zip(xs, ys, strict=True)) / sxx
    intercept = mean_y - slope * mean_x
    dof = len(xs) - 2
    residual = sum((y - intercept - slope * x) ** 2 for x, y in zip(xs, ys, strict=True)) / dof if dof else 0.0
    slope_se = (residual / sxx) ** 0.5
    # a trend only where the checks show one: the slope beyond its 99 % interval's half-width (Student's t), so
    # that scatter between checks does not announce a service
    if slope == 0 or abs(slope) <= _t99(dof) * slope_se:
        return slope, None, 1.0
    sign = 1.0 if slope > 0 else -1.0
    now_fit = mean_y + slope * (xs[-1] - mean_x)
    days = (sign - now_fit) / slope
    if days < 0:  # already beyond: the latest check says so
        days = 0.0
    if days > HORIZON_DAYS:
        return slope, None, sign
    return slope, points[-1][0] + dt.timedelta(days=days), sign


def _check(row: sa.Row[Any]) -> RigCheck:
    figures = json.loads(row.details or "{}").get("figures", {})
    drift = tuple((name, (figures.get(name) or {}).get("drift"), (figures.get(name) or {}).get("tolerance"))
                  for name, _, _ in COLUMNS)
    return RigCheck(str(row.checked_at), str(row.verdict), str(row.causes), str(row.checked_by), drift)


def rig_healths(store: HistoryStore, station: str | None = None, checks_each: int = CHECKS_SHOWN) -> list[RigHealth]:
    """Each station's rig (or one station's) as its newest registration's newest ``checks_each`` checks show it: two
    queries whatever the number of stations (a window over the checks), the trends computed here."""
    newest = sa.select(sa.func.max(reference_valves.c.id)).group_by(reference_valves.c.station)
    references = sa.select(reference_valves).where(reference_valves.c.id.in_(newest))
    ranked = sa.select(rig_checks, sa.func.row_number().over(partition_by=rig_checks.c.station,
                                                             order_by=rig_checks.c.id.desc()).label("rank"))
    if station is not None:
        references = references.where(reference_valves.c.station == station)
        ranked = ranked.where(rig_checks.c.station == station)
    newest_ids = sa.select(sa.func.max(reference_valves.c.id)).where(
        reference_valves.c.station == rig_checks.c.station).scalar_subquery()
    # a station's checks against its newest registration (or all of them where it has none)
    ranked = ranked.where(sa.or_(newest_ids.is_(None), rig_checks.c.reference_id == newest_ids)).subquery()
    with store.reading() as conn:
        found = {str(r.station): r for r in conn.execute(references)}
        checks: dict[str, list[RigCheck]] = {}
        for row in conn.execute(sa.select(ranked).where(ranked.c.rank <= checks_each).order_by(ranked.c.station,
                                                                                                  ranked.c.id)):
            checks.setdefault(str(row.station), []).append(_check(row))
    return [_health(name, found.get(name), checks.get(name, [])) for name in sorted(set(found) | set(checks))]


def _health(station: str, reference: sa.Row[Any] | None, checks: list[RigCheck]) -> RigHealth:
    """A station's rig from its registration and its checks (oldest first)."""
    measured = [c for c in checks if c.verdict != "SKIPPED"]
    drifts, due = [], None
    times = [parse_stored(c.checked_at) for c in measured]  # once per check, not per figure
    for k, (name, label, _unit) in enumerate(COLUMNS):
        points = [(when, float(drift) / float(tolerance)) for c, when in zip(measured, times, strict=True)
                  for _, drift, tolerance in (c.drift[k],) if drift is not None and tolerance and when is not None]
        slope, crossing, sign = _trend(points)
        drifts.append(FigureDrift(name, label, tuple((t.isoformat(), v) for t, v in points), slope,
                                  None if crossing is None else crossing.isoformat(timespec="seconds"), sign))
        if crossing is not None and (due is None or crossing < due[0]):
            due = (crossing, label)
    service_due, due_figure = (None, None) if due is None else (due[0].isoformat(timespec="seconds"), due[1])
    if measured and measured[-1].verdict != "GO":
        service_due, due_figure = "now", measured[-1].causes or "NO-GO"
    shown = None if reference is None else Reference(str(reference.valve_id), str(reference.variant),
                                                     str(reference.registered_at), str(reference.registered_by))
    return RigHealth(station, shown, tuple(checks), sum(c.verdict == "SKIPPED" for c in checks), tuple(drifts),
                     service_due, due_figure)


def _like(text: str) -> str:
    """``text`` as a LIKE prefix: its own % and _ matched as themselves."""
    return text.replace("\\", "\\\\").replace("%", "\\%").replace("_", "\\_") + "%"


def search(store: HistoryStore, text: str) -> list[ValveHit]:
    """Valves whose id, or whose pump's serial, begins with ``text``: each valve with its tests and latest test."""
    pattern = _like(text)
    found = sa.or_(tests.c.valve_id.like(pattern, escape="\\"), tests.c.pump_serial.like(pattern, escape="\\"))
    query = (sa.select(tests.c.valve_id, sa.func.max(tests.c.pump_serial),
                       sa.func.count(sa.distinct(tests.c.test_key)), sa.func.max(tests.c.started_at)).where(found)
             .group_by(tests.c.valve_id).order_by(sa.func.max(tests.c.started_at).desc()).limit(SEARCH_LIMIT))
    with store.reading() as conn:
        return [ValveHit(str(v), str(p), int(n), str(t)) for v, p, n, t in conn.execute(query)]


@dataclass(frozen=True)
class Indexing:
    """One indexing of a valve's test: its row, and ``state``: ``standing`` (its test as it stands), ``withdrawn``
    (its test withdrawn) or ``change`` (indexed again with other content: not what stands)."""

    row: TestRow
    state: str
    #: the row is not as its chain stored it (edited, or put in or taken out beside it): not to be trusted
    altered: bool = False


def valve_tests(store: HistoryStore, valve_id: str) -> list[Indexing]:
    """Every indexing of a valve's tests, oldest first, each with its state and whether its chain holds."""
    withdrawn = sa.select(amendments.c.target_id).where(amendments.c.target == "tests",
                                                         amendments.c.action == "withdraw")
    query = sa.select(tests, tests.c.id.in_(withdrawn).label("withdrawn_row"),
                      standing_tests().label("standing")).where(tests.c.valve_id == valve_id).order_by(tests.c.id)
    with store.reading() as conn:
        rows = list(conn.execute(query))
    withdrawn_keys = {r.test_key for r in rows if r.withdrawn_row}
    altered = store.altered_tests([r.id for r in rows])
    return [Indexing(TestRow.of(r._mapping), "withdrawn" if r.test_key in withdrawn_keys else "standing"
                     if r.standing else "change", r.id in altered) for r in rows]


def test_row(store: HistoryStore, test_id: int) -> sa.Row[Any] | None:
    """One row of ``tests`` by its id."""
    with store.reading() as conn:
        return conn.execute(sa.select(tests).where(tests.c.id == test_id)).first()


def stands(store: HistoryStore, test_id: int) -> bool:
    """Whether row ``test_id`` is its test as it stands (not withdrawn, not a later indexing with other content)."""
    with store.reading() as conn:
        return conn.execute(sa.select(tests.c.id).where(tests.c.id == test_id, standing_tests())).first() is not None


def retest_of(store: HistoryStore, record_dir: str) -> sa.Row[Any] | None:
    """The newest standing retest of the test whose record folder is ``record_dir`` (None: not retested)."""
    with store.reading() as conn:
        return conn.execute(sa.select(tests).where(tests.c.retest_of == record_dir, standing_tests())
                            .order_by(tests.c.id.desc()).limit(1)).first()


@dataclass(frozen=True, kw_only=True, slots=True)
class Adoption(AdoptionRow):
    """A station's adoption of a model (its row), with what it was decided on as figures (:attr:`decided_on`)."""

    #: the CSV's columns after the adoption's own (empty for an adoption without an evaluation)
    EVALUATION_COLUMNS: ClassVar[tuple[str, ...]] = (
        "cv_accuracy", "labels", "worn_or_faulty", "folds", "worn_passed", "reusable_failed", "marginal",
        "replaced_model", "replaced_accuracy", "replaced_worn_passed", "replaced_reusable_failed", "replaced_in_sample")

    @property
    def decided_on(self) -> CandidateEvaluation | None:
        """The evaluation the model was adopted on (None: the model carried none, e.g. the shipped one, or it was
        adopted before the history kept them)."""
        return CandidateEvaluation.from_json(self.evaluation)

    def evaluation_cells(self) -> tuple[object, ...]:
        """The evaluation's figures in the order of :attr:`EVALUATION_COLUMNS`."""
        e = self.decided_on
        if e is None:
            return ("",) * len(self.EVALUATION_COLUMNS)
        return (round(e.candidate.accuracy, 4), e.labels, e.worn_or_faulty, e.folds, e.candidate.worn_passed,
                e.candidate.reusable_failed, e.candidate.marginal, e.replaced.model, round(e.replaced.accuracy, 4),
                e.replaced.worn_passed, e.replaced.reusable_failed, e.replaced.in_sample)


def _adoption(row: sa.Row[Any]) -> Adoption:
    return Adoption.of(row._mapping)


def models(store: HistoryStore) -> tuple[list[Adoption], list[Adoption]]:
    """Each station's model as it stands (its newest adoption), and the adoptions, newest first (at most 200)."""
    newest = sa.select(sa.func.max(adoptions.c.id)).group_by(adoptions.c.station)
    with store.reading() as conn:
        current = [_adoption(row) for row in conn.execute(sa.select(adoptions).where(adoptions.c.id.in_(newest))
                                                          .order_by(adoptions.c.station))]
        every = [_adoption(row) for row in conn.execute(sa.select(adoptions).order_by(adoptions.c.id.desc())
                                                        .limit(200))]
    return current, every
