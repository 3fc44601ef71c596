"""The history's refusals are told apart by the database's error codes, not by the words of its messages (#54)."""

from __future__ import annotations

from pathlib import Path

import pytest
import sqlalchemy as sa

from edc_bench.bench import run_simulated_test
from edc_bench.config import load_variant
from edc_bench.history.guard import problem, raised_by_history
from edc_bench.history.store import HistoryStore
from edc_bench.records.reader import load_record
from edc_bench.records.record import write_record


@pytest.fixture(scope="module")
def record_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """One simulated test's record folder."""
    return write_record(run_simulated_test(load_variant(), "new", 3), tmp_path_factory.mktemp("records"),
                        figure=False)


def _error(url: str, statement: str) -> sa.exc.DBAPIError:
    engine = sa.create_engine(url)
    try:
        with engine.begin() as conn:
            conn.execute(sa.text(statement))
    except sa.exc.DBAPIError as exc:
        return exc
    finally:
        engine.dispose()
    raise AssertionError(f"{statement!r} was not refused")


def test_a_trigger_refusal_is_shown_in_the_databases_words_on_both_databases(db_url: str, record_dir: Path) -> None:
    store = HistoryStore(db_url, warn=lambda _line: None)
    store.add(load_record(record_dir), record_dir)
    store.close()
    refused = _error(db_url, "DELETE FROM tests")
    assert raised_by_history(refused.orig)
    assert problem(refused, "read", "db").startswith("edc-bench history is append-only: DELETE on table tests")


def test_a_message_that_only_says_append_only_is_not_taken_for_the_historys_own(db_url: str) -> None:
    # an error whose text holds the trigger's words (here a table named so) is the database's error, not a refusal
    refused = _error(db_url, 'SELECT * FROM "edc-bench history is append-only"')
    assert not raised_by_history(refused.orig)
    assert problem(refused, "read", "db").startswith("history database db: ")


def test_a_damaged_sqlite_file_is_known_by_its_code(tmp_path: Path) -> None:
    path = tmp_path / "history.sqlite"
    path.write_bytes(b"not a database " * 400)
    refused = _error(f"sqlite:///{path}", "SELECT 1 FROM sqlite_master")
    assert "is damaged (file is not a database)" in problem(refused, "read", f"sqlite:///{path}")
