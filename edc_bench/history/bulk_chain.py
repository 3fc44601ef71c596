"""A chain of a hundred stations and a million tests in a PostgreSQL history, for the web view's benchmark.

Rows are copied in bulk (PostgreSQL's COPY) with the database's triggers off for this session
(``session_replication_role = replica``, a superuser's right): a million rows through the chain's per-row trigger
would take hours, and the benchmark measures reading, not writing. So the rows carry no hashes: they are what the
chain calls rows written before it (``history --verify`` says so). Never run this against a shop's history: it
refuses a database that holds any test.

    python -m edc_bench.history.bulk_chain --db postgresql+psycopg://postgres@127.0.0.1/bench --tests 1000000

Each station tests every day of the year before ``now`` (about 27 a day for a million over a hundred stations),
one in eight a MARGINAL retested at once, one in 997 indexed again with other content, INVALID tests with where they point; each station registers a reference
valve and checks its rig weekly (one rig in ten drifting towards its limit, one NO-GO); two adoptions per
station; one withdrawal per station.
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import sys
from collections.abc import Sequence

import numpy as np
import sqlalchemy as sa

from edc_bench.history.demo_chain import REFERENCE, TOLERANCES
from edc_bench.history.schema import FIGURES

TEST_COLUMNS = ("id", "record_dir", "started_at", "valve_id", "pump_serial", "variant", "part_number", "verdict", "af_v",
                "a1_v_s_per_mm", "af_rel", "a1_rel", "probability_faulty", "distance", "station", "operator", "clock",
                "software_version", "reason", "simulated", "retest_of", "decision", "record_sha256", "indexed_at",
                "indexed_by", "test_key", "legacy_key", "invalid_area", "first_indexing")
#: One test in this many is indexed again with other content (a change every reader shows; not a test of its own).
REINDEXED_ONE_IN = 997
VERDICTS = ("PASS", "FAIL", "MARGINAL", "INVALID")
#: The pump types the chain tests (the shipped variant and five others, as many of each).
VARIANTS = ("p-edc-default", "p-edc-6cyl", "p-edc-8cyl", "p-edc-marine", "p-edc-genset", "p-edc-rail")
AREAS = ("mounting", "bus", "rig", "PC", "calibration")


def technician(station: str, n: int) -> str:
    """Who ran test ``n`` at ``station``: three technicians a station, each at their own station."""
    return f"tech {station.removeprefix('Station ')}-{n % 3}"


def station_name(k: int) -> str:
    """The benchmark's station ``k``."""
    return f"Station {k:03d}"


def _iso(when: dt.datetime) -> str:
    return when.isoformat(timespec="seconds")


def _copy_tests(cursor: object, count: int, stations: int, now: dt.datetime, rng: np.random.Generator) -> int:
    """Copy ``count`` test rows (first tests and their retests); returns the rows written."""
    firsts = int(count / 1.12)  # one in eight MARGINAL first tests is followed by its retest
    seconds = rng.uniform(0, 365 * 86400, firsts)
    order = np.argsort(-seconds)  # test numbers rise with time, as a chain's ids do
    station = rng.integers(0, stations, firsts)
    verdict = rng.choice(4, firsts, p=(0.55, 0.22, 0.12, 0.11))
    area = rng.integers(0, len(AREAS), firsts)
    written = 0
    with cursor.copy(f"COPY tests ({', '.join(TEST_COLUMNS)}) FROM STDIN") as copy:  # type: ignore[attr-defined]
        for n, k in enumerate(order):
            if written >= count:
                break
            when = now - dt.timedelta(seconds=float(seconds[k]))
            name, v = station_name(int(station[k])), VERDICTS[int(verdict[k])]
            folder = f"bulk:{name}/{n}"
            written += 1
            copy.write_row((written, *_row(folder, when, f"V-{n:07d}", name, n, v,
                                           AREAS[int(area[k])] if v == "INVALID" else None, None, None)))
            if n % REINDEXED_ONE_IN == 0 and written < count:
                written += 1
                copy.write_row((written, *_row(folder, when, f"V-{n:07d}", name, n, "PASS", None, None, None,
                                               first=False)))
            if v == "MARGINAL" and written < count:
                second = "PASS" if n % 2 else "FAIL"
                written += 1
                copy.write_row((written, *_row(f"{folder}/retest", when + dt.timedelta(minutes=20), f"V-{n:07d}",
                                               name, n, second, None, folder, second, retest=True)))
    return written


def _row(folder: str, when: dt.datetime, valve: str, station: str, n: int, verdict: str, area: str | None,
         retest_of: str | None, decision: str | None, retest: bool = False, first: bool = True
         ) -> tuple[object, ...]:
    rel = {"PASS": 1.1, "MARGINAL": 1.45, "FAIL": 1.9}.get(verdict, 1.0) + (n % 7) * 0.01
    started = _iso(when)
    key = f"bulk:{n}" + ("r" if retest else "")
    return (folder, started, valve, f"P-{n % 50000:05d}", VARIANTS[n % len(VARIANTS)], "0 402 196 700", verdict,
            0.3 * rel, 0.011 * rel, rel, rel, min(1.0, max(0.0, rel - 1.2)), (rel - 1.5) * 2, station,
            technician(station, n),
            "real-time", "bench", "" if verdict != "INVALID" else "not judged", False, retest_of, decision,
            f"{n:064x}" if first else f"{n:063x}f", started, "bulk", key, "legacy:" + key, area, first)


def _checks(conn: sa.Connection, stations: int, now: dt.datetime, rng: np.random.Generator) -> int:
    """Each station's reference valve and 52 weekly self-checks; returns the checks written."""
    from edc_bench.history.schema import reference_valves, rig_checks

    registered = now - dt.timedelta(days=365)
    references = [{"id": k + 1, "station": station_name(k), "valve_id": f"REF-{k}", "variant": "p-edc-default", **REFERENCE,
                   "lvdt_at_floor": False, "coil_temp_c": 20.0, "simulated": False, "details": "{}",
                   "software_version": "bench", "registered_by": "owner", "registered_at": _iso(registered)}
                  for k in range(stations)]
    conn.execute(reference_valves.insert(), references)
    ids = dict(conn.execute(sa.select(reference_valves.c.station, reference_valves.c.id)).all())
    rows: list[dict[str, object]] = []
    for k in range(stations):
        for week in range(52):
            drift = {name: float(rng.uniform(-0.25, 0.25)) * TOLERANCES[name] for name in FIGURES}
            no_go = k % 10 == 1 and week == 51
            drift.update({"af_v": 0.0003 * week} if k % 10 == 0 else {}, **({"lvdt_zero_mm": 0.035} if no_go else {}))
            figures = {name: {"drift": d, "tolerance": TOLERANCES[name]} for name, d in drift.items()}
            rows.append({"id": len(rows) + 1, "station": station_name(k), "reference_id": ids[station_name(k)],
                         "verdict": "NO-GO" if no_go else "GO", "causes": "LVDT zero" if no_go else "",
                         "words": "rig self-check", **{name: REFERENCE[name] + drift[name] for name in FIGURES},
                         "lvdt_at_floor": False, "coil_temp_c": 20.0, "simulated": False,
                         "details": json.dumps({"figures": figures}), "software_version": "bench",
                         "checked_by": "tech", "checked_at": _iso(registered + dt.timedelta(days=7 * week + 3))})
    conn.execute(rig_checks.insert(), rows)
    return len(rows)


def fill_bulk_chain(url: str, tests: int, stations: int = 100, now: dt.datetime | None = None,
                    seed: int = 1) -> dict[str, int]:
    """Fill an empty PostgreSQL history (at this edc-bench's revision; a superuser's URL) with the benchmark's chain.

    Returns what was written. Raises ValueError for a database that holds tests already.
    """
    from edc_bench.history.day_counts import KEY, MONTH_KEY, recount
    from edc_bench.history.schema import adoptions, amendments, edc_logins, test_day_counts, test_month_counts
    from edc_bench.history.schema import tests as tests_table

    now = (now or dt.datetime.now(dt.UTC)).replace(microsecond=0)
    rng = np.random.default_rng(seed)
    engine = sa.create_engine(url)
    try:
        with engine.begin() as conn:
            if conn.execute(sa.select(sa.func.count()).select_from(tests_table)).scalar():
                raise ValueError("this history holds tests already: the benchmark's chain goes into an empty one")
            conn.exec_driver_sql("SET LOCAL session_replication_role = replica")  # no per-row triggers: bulk
            cursor = conn.connection.cursor()
            written = _copy_tests(cursor, tests, stations, now, rng)
            checks = _checks(conn, stations, now, rng)
            conn.execute(edc_logins.insert(), [{"id": k + 1, "login": f"station{k:03d}", "station": station_name(k),
                                                "mapped_by": "owner", "mapped_at": _iso(now)} for k in range(stations)])
            conn.execute(adoptions.insert(), [{"id": 2 * k + j + 1, "station": station_name(k),
                                               "model_name": f"model-{j}",
                                               "model_sha256": f"{j}" * 64, "adopted_by": "owner",
                                               "adopted_at": _iso(now - dt.timedelta(days=200 - 100 * j))}
                                              for k in range(stations) for j in range(2)])
            first_ids = conn.execute(sa.select(sa.func.min(tests_table.c.id)).where(tests_table.c.first_indexing)
                                     .group_by(tests_table.c.station).order_by(sa.func.min(tests_table.c.id))).scalars()
            conn.execute(amendments.insert(), [{"id": n + 1, "target": "tests", "target_id": i, "action": "withdraw",
                                                "reason": "benchmark", "amended_by": "owner",
                                                "amended_at": _iso(now)} for n, i in enumerate(first_ids)])
            # what revisions 0008 and 0009's trigger counts row by row, counted at once (the triggers are off)
            conn.execute(test_day_counts.insert().from_select([*KEY, "tests"], recount()))
            conn.execute(test_month_counts.insert().from_select([*MONTH_KEY, "tests"], recount("month")))
            # the rows came with their ids: each table's sequence goes on after them, so rows written later get new
            # ones (a login mapped, a test indexed on the benchmark's chain)
            for table in ("tests", "rig_checks", "reference_valves", "edc_logins", "adoptions", "amendments"):
                conn.exec_driver_sql(f"SELECT setval(pg_get_serial_sequence('{table}', 'id'), "
                                     f"(SELECT coalesce(max(id), 0) + 1 FROM {table}), false)")
        with engine.connect() as conn:
            conn.execution_options(isolation_level="AUTOCOMMIT").exec_driver_sql("ANALYZE")
    finally:
        engine.dispose()
    return {"tests": written, "checks": checks, "stations": stations}


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m edc_bench.history.bulk_chain``."""
    parser = argparse.ArgumentParser(prog="python -m edc_bench.history.bulk_chain", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--db", required=True, help="postgresql+psycopg://SUPERUSER@HOST/DB (an empty history)")
    parser.add_argument("--tests", type=int, default=1_000_000)
    parser.add_argument("--stations", type=int, default=100)
    args = parser.parse_args(argv)
    try:
        print(fill_bulk_chain(args.db, args.tests, args.stations))
    except (ValueError, sa.exc.SQLAlchemyError) as exc:
        print(f"bulk_chain: error: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
