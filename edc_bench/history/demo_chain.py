"""A made-up chain of shops in a station's SQLite history, to look at the web view and to test it: stations with
tests over weeks (each verdict, INVALID tests with where they point, MARGINAL retests), one test withdrawn and one
indexed again with other content, each station's reference valve and self-checks (one rig drifting towards its
limit, one NO-GO, one check skipped), model adoptions, and valve ids holding the characters scans have held
(``<``, ``;``, quotes, non-ASCII). Rows only: no record folders (``record_dir`` says ``demo-chain:``).

Every row is written as the history writes it (hash-chained, append-only), with the times the demo says: on
SQLite the history trusts the writer's clock, which is what lets a demo span weeks (on PostgreSQL the server
stamps each row itself).

    python -m edc_bench.history.demo_chain --db sqlite:///demo.sqlite
    edc-bench web --db sqlite:///demo.sqlite
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import random
import sys
import zlib
from collections.abc import Mapping, Sequence
from typing import NamedTuple

import sqlalchemy as sa

from edc_bench.history.schema import FIGURES, adoptions, amendments, reference_valves, rig_checks, tests
from edc_bench.history.store import HistoryStore, legacy_test_key

#: the tolerance of each self-check figure (absolute for the two zeros, relative for the rest), as the variants'
#: [selfcheck] sections give them by default
TOLERANCES = {"lvdt_zero_mm": 0.02, "current_zero_a": 0.01, "coil_r20_ohm": 0.015, "a0_v_per_mm": 0.015,
              "af_v": 0.02, "a1_v_s_per_mm": 0.02}
REFERENCE = {"lvdt_zero_mm": 0.0, "current_zero_a": 0.0, "coil_r20_ohm": 2.4, "a0_v_per_mm": 0.9, "af_v": 0.35,
             "a1_v_s_per_mm": 0.012}
#: valve ids as scans have typed them
ODD_VALVE_IDS = ('V-<script>alert("x")</script>', "V-1'; DROP TABLE tests;--", "V-Ölpumpe-Ä7")


def _iso(when: dt.datetime) -> str:
    return when.astimezone(dt.UTC).isoformat(timespec="seconds")


class DemoTest(NamedTuple):
    """What the demo needs back of a test it wrote."""

    id: int
    record_dir: str
    test_key: str
    operator: str


def _write(store: HistoryStore, table: sa.Table, row: Mapping[str, object]) -> int:
    """One row, chained as the history chains it, with the demo's own times (SQLite only); returns its id."""
    with store._writing("demo") as conn:  # noqa: SLF001 - the history's own writer, with the demo's clock
        stored = store._append(conn, table, dict(row))  # noqa: SLF001
    assert stored is not None
    return int(stored.get("id", 0))


def _test(store: HistoryStore, rng: random.Random, *, when: dt.datetime, station: str, operator: str,
          valve: str, verdict: str, area: str | None = None, retest_of: str | None = None,
          decision: str | None = None, variant: str = "p-edc-default", key: str | None = None,
          record_dir: str | None = None, af_rel: float | None = None) -> DemoTest:
    af_rel = af_rel if af_rel is not None else {"PASS": 1.1, "MARGINAL": 1.45, "FAIL": 1.9}.get(verdict, 1.0)
    af_rel *= 1 + rng.uniform(-0.05, 0.05)
    started = _iso(when)
    folder = record_dir or f"demo-chain:{station}/{started}/{valve}"
    pump = f"P-{zlib.crc32(valve.encode()) % 9000 + 1000}"
    row = {"record_dir": folder, "started_at": started, "valve_id": valve, "pump_serial": pump,
           "variant": variant, "part_number": "0 402 196 700" if variant == "p-edc-default" else "0 402 196 710",
           "verdict": verdict, "af_v": 0.3 * af_rel, "a1_v_s_per_mm": 0.011 * (0.5 + af_rel / 2), "af_rel": af_rel,
           "a1_rel": 0.5 + af_rel / 2, "probability_faulty": min(1.0, max(0.0, (af_rel - 1.2) * 1.5)),
           "distance": (af_rel - 1.5) * 2, "station": station, "operator": operator, "clock": "real-time",
           "software_version": "demo", "reason": "" if verdict != "INVALID" else f"not judged: check the {area}",
           "model_name": None, "model_sha256": None, "simulated": False, "retest_of": retest_of,
           "decision": decision, "invalid_area": area if verdict == "INVALID" else None,
           "part": {"PASS": "none", "MARGINAL": "none", "FAIL": "valve or rack"}.get(verdict),
           "indexed_at": _iso(when + dt.timedelta(minutes=2)),
           "indexed_by": operator, "db_login": None}
    key = key or f"demo:{folder}"
    row.update(test_key=key, legacy_key=legacy_test_key(started, valve, pump, station, retest_of or ""))
    return DemoTest(_write(store, tests, row), folder, key, operator)


def _station_names(stations: int) -> list[str]:
    cities = ("Nord", "Süd", "Ost", "West", "Mitte", "Hafen", "Berg", "Tal")
    return [f"Werkstatt {cities[k]} {k + 1}" if k < len(cities) else f"Station {k + 1}" for k in range(stations)]


def _fill_tests(store: HistoryStore, rng: random.Random, names: list[str], start: dt.datetime, now: dt.datetime,
                days: int, tests_per_day: int) -> int:
    """Each station's tests, day by day (a MARGINAL retested 20 minutes later); the last station goes quiet ten
    days before ``now``. Returns how many were written."""
    operators = ("ana", "jonas", "mira", "ole")
    areas = ("mounting", "bus", "rig", "PC", "calibration", "mounting", "bus", "mounting")
    count, valve_number = 0, 1000
    for s, station in enumerate(names):
        quiet_from = now - dt.timedelta(days=10) if s == len(names) - 1 and len(names) > 1 else now
        for day in range(days):
            for n in range(tests_per_day):
                when = start + dt.timedelta(days=day, hours=7 + 2 * n, minutes=rng.randrange(60))
                if when >= quiet_from:
                    continue
                valve_number += 1
                verdict = rng.choices(("PASS", "FAIL", "MARGINAL", "INVALID"), (50, 25, 12, 13))[0]
                first = _test(store, rng, when=when, station=station, operator=operators[(s + n) % 4],
                              valve=f"V-{valve_number}", verdict=verdict, area=areas[rng.randrange(len(areas))])
                count += 1
                if verdict == "MARGINAL":
                    second = rng.choice(("PASS", "FAIL"))
                    _test(store, rng, when=when + dt.timedelta(minutes=20), station=station, operator=first.operator,
                          valve=f"V-{valve_number}", verdict=second, retest_of=first.record_dir, decision=second)
                    count += 1
    return count


def _fill_stories(store: HistoryStore, rng: random.Random, names: list[str], start: dt.datetime) -> int:
    """One valve's four visits as it wears, the ids scans have held, a test withdrawn (its id typed wrong) and one
    indexed again with other content (a PASS over its FAIL). Returns the tests written."""
    for k, (verdict, rel) in enumerate((("PASS", 1.05), ("PASS", 1.2), ("MARGINAL", 1.42), ("FAIL", 1.8))):
        _test(store, rng, when=start + dt.timedelta(days=2 + 7 * k, hours=15), station=names[0], operator="ana",
              valve="V-0815", verdict=verdict, af_rel=rel)
    for k, valve in enumerate(ODD_VALVE_IDS):
        _test(store, rng, when=start + dt.timedelta(days=3 + k, hours=16), station=names[min(1, len(names) - 1)],
              operator="jonas <j@shop>", valve=valve, verdict="PASS")
    wrong = _test(store, rng, when=start + dt.timedelta(days=5, hours=17), station=names[0], operator="ana",
                  valve="V-0815-typo", verdict="FAIL")
    _write(store, amendments, {"target": "tests", "target_id": wrong.id, "action": "withdraw",
                               "reason": "valve id typed wrong; retested as V-0815", "amended_by": "ines",
                               "amended_at": _iso(start + dt.timedelta(days=5, hours=18)), "db_login": None})
    first = _test(store, rng, when=start + dt.timedelta(days=6, hours=9), station=names[0], operator="ana",
                  valve="V-4711", verdict="FAIL")
    _test(store, rng, when=start + dt.timedelta(days=6, hours=9), station=names[0], operator="ana", valve="V-4711",
          verdict="PASS", key=first.test_key, record_dir=first.record_dir)
    return 4 + len(ODD_VALVE_IDS) + 2


def _check_row(station: str, reference_id: int, when: dt.datetime, drift: dict[str, float], no_go: bool,
               by: str) -> dict[str, object]:
    figures = {name: {"drift": drift[name], "tolerance": TOLERANCES[name], "out": abs(drift[name]) > TOLERANCES[name],
                      "registered": REFERENCE[name]} for name in FIGURES}
    measured = {name: REFERENCE[name] + drift[name] if name in ("lvdt_zero_mm", "current_zero_a")
                else REFERENCE[name] * (1 + drift[name]) for name in FIGURES}
    return {"station": station, "reference_id": reference_id, "verdict": "NO-GO" if no_go else "GO",
            "causes": "LVDT zero" if no_go else "", "words": "rig self-check " + ("NO-GO" if no_go else "GO"),
            **measured, "lvdt_at_floor": False, "coil_temp_c": 20.0, "simulated": False,
            "details": json.dumps({"figures": figures, "test_problems": []}), "software_version": "demo",
            "checked_by": by, "checked_at": _iso(when), "db_login": None}


def _fill_rigs(store: HistoryStore, rng: random.Random, names: list[str], start: dt.datetime, now: dt.datetime,
               days: int) -> int:
    """Each station's reference valve and its weekly self-checks: the first station's af drifts 0.4 % a week, the
    second's last check is NO-GO (the LVDT's zero), the third skipped its last. Returns the checks written."""
    count = 0
    for s, station in enumerate(names):
        registered = start - dt.timedelta(days=1)
        reference = _write(store, reference_valves, {
            "station": station, "valve_id": f"REF-{s + 1}", "variant": "p-edc-default", **REFERENCE,
            "lvdt_at_floor": False, "coil_temp_c": 20.0, "simulated": False, "valve_spec": None,
            "details": json.dumps({"test_problems": []}), "software_version": "demo", "registered_by": "ines",
            "registered_at": _iso(registered), "db_login": None})
        weeks = max(1, days // 7)
        for week in range(weeks):
            when = registered + dt.timedelta(days=7 * (week + 1) - 0.5)
            if when >= now:
                break
            count += 1
            if s == 2 and week == weeks - 1:
                _write(store, rig_checks, {"station": station, "reference_id": reference, "verdict": "SKIPPED",
                                           "causes": "", "words": "due self-check skipped", "simulated": False,
                                           "details": json.dumps({"due": "weekly"}), "software_version": "demo",
                                           "checked_by": "mira", "checked_at": _iso(when), "db_login": None})
                continue
            no_go = s == 1 and week == weeks - 1
            drift = {name: rng.uniform(-0.25, 0.25) * TOLERANCES[name] for name in FIGURES}
            drift.update({"af_v": 0.004 * (week + 1) + rng.uniform(-0.001, 0.001)} if s == 0 else {},
                         **({"lvdt_zero_mm": 0.035} if no_go else {}))
            _write(store, rig_checks, _check_row(station, reference, when, drift, no_go,
                                                 ("ana", "jonas", "mira", "ole")[s % 4]))
    return count


def fill_demo_chain(store: HistoryStore, *, stations: int = 4, days: int = 28, tests_per_day: int = 3,
                    now: dt.datetime | None = None, seed: int = 1) -> dict[str, int]:
    """Fill a station's SQLite history with a made-up chain (see the module's docstring); returns what was
    written. The last station goes quiet ten days before ``now``; the first one's rig drifts."""
    if not store.is_sqlite:
        raise ValueError("the demo chain writes its own times: a SQLite history only")
    with store.reading() as conn:
        if conn.execute(sa.select(sa.func.count()).select_from(tests)).scalar():
            raise ValueError(f"{store.shown_url} holds tests already: the demo chain goes into a new history, never "
                             "a station's (its rows could not be taken out again)")
    rng = random.Random(seed)
    now = (now or dt.datetime.now(dt.UTC)).replace(microsecond=0)
    start = now - dt.timedelta(days=days)
    names = _station_names(stations)
    written_tests = _fill_tests(store, rng, names, start, now, days, tests_per_day) + _fill_stories(store, rng, names,
                                                                                                   start)
    checks = _fill_rigs(store, rng, names, start, now, days)
    for s, station in enumerate(names[:2]):
        _write(store, adoptions, {"station": station, "model_name": f"shop-2026-{s + 10}", "model_sha256": f"{s}" * 64,
                                  "adopted_by": "ines", "adopted_at": _iso(start + dt.timedelta(days=14)),
                                  "db_login": None, "evaluation": _evaluation(f"shop-2026-{s + 10}", 120 + 40 * s)})
    return {"tests": written_tests, "checks": checks, "adoptions": min(2, len(names))}


def _evaluation(name: str, labels: int) -> str:
    """What a demo adoption was decided on: figures of the kind a shop's 5-fold cross-validation gives."""
    from edc_bench.learning.candidate_evaluation import CandidateEvaluation, Score

    worn = labels // 3
    candidate = Score(f"{name} (cross-validated)", labels, 0.93, 6, 0.96, 2, 3)
    shipped = Score("p-edc-default", labels, 0.81, 9, 0.84, worn // 3, 4)
    return CandidateEvaluation(5, labels, worn, candidate, shipped, "a" * 64).to_json()


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m edc_bench.history.demo_chain``: fill a new SQLite history with the demo chain."""
    parser = argparse.ArgumentParser(prog="python -m edc_bench.history.demo_chain", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--db", required=True, help="sqlite:///FILE (a new file)")
    parser.add_argument("--stations", type=int, default=4)
    parser.add_argument("--days", type=int, default=28)
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args(argv)
    try:
        with HistoryStore(args.db) as store:
            counts = fill_demo_chain(store, stations=args.stations, days=args.days, seed=args.seed)
    except (ValueError, OSError) as exc:
        print(f"demo_chain: error: {exc}", file=sys.stderr)
        return 2
    print(f"demo chain in {args.db}: {counts}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
