"""The web view's benchmark at a small scale on the tests' PostgreSQL server: the bulk chain is what the pages
expect (a hundred stations, a table of rigs), and every page the benchmark times answers (docs/performance.md
holds the million-test figures, measured by ``python docs/regenerate.py --measure performance-web``)."""

from __future__ import annotations

import pytest
import sqlalchemy as sa

from edc_bench.history.bulk_chain import fill_bulk_chain
from edc_bench.history.store import Filters, HistoryStore
from edc_bench.history.summary import chain_summary
from edc_bench.web.benchmark import measure, pages


def test_the_bulk_chain_fills_an_empty_history_and_every_timed_page_answers(postgres_db: str) -> None:
    written = fill_bulk_chain(postgres_db, 3000, stations=20)
    assert written["tests"] == 3000 and written["checks"] == 20 * 52
    engine = sa.create_engine(postgres_db)
    with engine.connect() as conn:
        again = conn.exec_driver_sql("SELECT count(*) FROM tests WHERE NOT first_indexing").scalar()
    engine.dispose()
    assert again == 3  # one test in 997 indexed again with other content (tests 0, 997 and 1994)
    with HistoryStore(postgres_db) as store:
        summary = chain_summary(store, Filters(simulated=False))
        assert summary.tests == 3000 - 20 - again  # one withdrawal per station; a change is no test of its own
        assert summary.retests > 0 and len(summary.stations) == 20 and summary.period == "month"
        assert summary.per_day and all(len(d.day) == 7 for d in summary.per_day)
    timings = measure(postgres_db, requests=1)
    assert len(timings) == 13 and all(t.p50_ms > 0 for t in timings)
    with pytest.raises(ValueError, match="holds tests already"):
        fill_bulk_chain(postgres_db, 10)


def test_every_page_the_benchmark_times_asks_only_for_filters_the_page_has() -> None:
    """The review of #55: the pump type's pages were timed with a query name the chain page does not read, so
    they timed the unfiltered page."""
    import datetime as dt
    import re
    from pathlib import Path

    import edc_bench.web

    form = (Path(edc_bench.web.__file__).parent / "templates" / "chain.html").read_text(encoding="utf-8")
    fields = set(re.findall(r'<input[^>]* name="([a-z_]+)"', form))
    asked = {key for _, path, query in pages(dt.datetime(2026, 11, 29)) if path.startswith("/chain") for key in query}
    assert asked and asked <= fields, asked - fields


def test_the_bulk_chain_refuses_a_history_that_is_not_empty(postgres_db: str) -> None:
    engine = sa.create_engine(postgres_db)
    with engine.begin() as conn:
        conn.exec_driver_sql("INSERT INTO edc_logins (login, mapped_by, mapped_at) VALUES ('x', 'y', 'z')")
    engine.dispose()
    with HistoryStore(postgres_db) as store:
        store.add_row({"record_dir": "/r", "started_at": "2026-11-20T08:00:00+00:00", "valve_id": "V",
                       "pump_serial": "P",
                       "variant": "v", "part_number": "p", "verdict": "PASS", "station": "s", "operator": "o",
                       "clock": "real-time", "software_version": "t", "reason": ""})
    with pytest.raises(ValueError, match="holds tests already"):
        fill_bulk_chain(postgres_db, 10)
