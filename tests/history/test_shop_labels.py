"""Teardown labels, training from them, adopting the candidate, and a simulated shop that shows what they teach."""

from __future__ import annotations

import json
import sqlite3
from pathlib import Path

import numpy as np
import pytest
from helpers import edc_bench

from edc_bench.errors import ConfigError
from edc_bench.history import migrate
from edc_bench.history.store import COLUMNS, HistoryStore
from edc_bench.records.reader import load_record
from edc_bench.learning.shop_training import LabelledTests, train_from_labels
from edc_bench.verdict.classifier import ValveClassifier, default_classifier, packaged_model_path


def _row(valve: str, started: str, af_rel: float | None, a1_rel: float | None, verdict: str = "PASS",
         n: int = 0) -> dict:
    row = {name: "" for name in COLUMNS if name not in ("id", "record_sha256", "indexed_at", "indexed_by")}
    row.update(record_dir=f"/records/{valve}-{started}-{n}", started_at=started, valve_id=valve, verdict=verdict,
               af_v=None, a1_v_s_per_mm=None, af_rel=af_rel, a1_rel=a1_rel, probability_faulty=None, distance=None,
               model_name=None, model_sha256=None, coil_r20_ohm=None, coil_in_spec=None, model_fits=None,
               stop_reason=None, test_s=None, simulated=None)
    return row


def _synthetic_shop(store: HistoryStore, count: int, seed: int = 3) -> None:
    """Valves whose teardown calls worn what lies beyond 1.2 in both ratios (stricter than the shipped model)."""
    rng = np.random.default_rng(seed)
    for n in range(count):
        af_rel, a1_rel = rng.uniform(0.8, 1.8, 2)
        valve = f"S{n:03d}"
        store.add_row(_row(valve, f"2026-03-{1 + n % 28:02d}T08:00:00+00:00", af_rel, a1_rel, n=n))
        worn = af_rel + a1_rel > 2.4
        store.add_teardown(valve, "worn" if worn else "reusable", labelled_by="test",
                           labelled_at=f"2026-03-{1 + n % 28:02d}T12:00:00")


def test_a_teardown_labels_the_valves_last_judged_test_before_it(tmp_path: Path) -> None:
    with HistoryStore(f"sqlite:///{tmp_path / 'h.sqlite'}") as store:
        store.add_row(_row("V1", "2026-05-01T08:00:00+00:00", 1.1, 1.2))
        store.add_row(_row("V1", "2026-05-02T08:00:00+00:00", 1.3, 1.4))  # the last judged one before
        store.add_row(_row("V1", "2026-05-02T09:00:00+00:00", None, None, verdict="INVALID"))  # not judged
        store.add_row(_row("V1", "2026-05-09T08:00:00+00:00", 1.0, 1.0))  # after the teardown: a rebuilt valve
        store.add_teardown("V1", "worn", labelled_by="ana", labelled_at="2026-05-03", clearance_mm=0.21)
        store.add_teardown("V9", "reusable", labelled_by="ana", labelled_at="2026-05-03")  # never tested
        labelled = store.labelled_tests()
        assert [(m.test.valve_id, m.test.af_rel, m.label, m.teardown.clearance_mm) for m in labelled
                if m.test is not None] == [("V1", 1.3, 1, 0.21)]
        assert [m.teardown.valve_id for m in store.unmatched_teardowns()] == ["V9"]
        with pytest.raises(ConfigError, match="reusable, worn, faulty"):
            store.add_teardown("V1", "broken", labelled_by="ana", labelled_at="2026-05-03")
        # opened again a week later with no test between: that teardown labels nothing (a test labels once)
        store.add_teardown("V1", "reusable", labelled_by="ana", labelled_at="2026-05-08")
        assert [(m.test.af_rel, m.teardown.finding) for m in store.labelled_tests() if m.test] == [(1.3, "worn")]
        # the finding was a typing error: withdrawn, and the second corrected; the right one labels the test
        first = store.teardowns("V1")[0]
        store.withdraw_teardown(first.id, "typed worn for reusable")
        second = store.teardowns("V1")[0]
        store.add_teardown("V1", "reusable", labelled_by="ana", labelled_at="2026-05-03", corrects=second.id)
        assert [(m.test.af_rel, m.teardown.finding) for m in store.labelled_tests() if m.test] == [(1.3, "reusable")]
        with pytest.raises(ConfigError, match="no teardown finding with id 999"):
            store.withdraw_teardown(999, "no such")
        with pytest.raises(ConfigError, match=f"finding {first.id} is withdrawn or corrected already"):
            store.withdraw_teardown(first.id, "twice")
        # nothing was deleted: the audit trail holds all three findings and the withdrawal
        events = [e.event for e in store.audit("V1")]
        assert events.count("finding recorded") == 3 and f"finding {first.id} withdrawn" in events


def test_an_older_history_gets_the_new_columns_and_keeps_its_rows(tmp_path: Path) -> None:
    path = tmp_path / "old.sqlite"
    with sqlite3.connect(path) as conn:  # as an edc-bench before schema revisions made it: no model columns,
        conn.execute("CREATE TABLE tests (id INTEGER NOT NULL PRIMARY KEY, record_dir VARCHAR(1024) NOT NULL "
                     "UNIQUE, started_at VARCHAR(40) NOT NULL, valve_id VARCHAR(200) NOT NULL, pump_serial "
                     "VARCHAR(200) NOT NULL, variant VARCHAR(200) NOT NULL, part_number VARCHAR(100) NOT NULL, "
                     "verdict VARCHAR(20) NOT NULL, af_v FLOAT, a1_v_s_per_mm FLOAT, af_rel FLOAT, a1_rel FLOAT, "
                     "probability_faulty FLOAT, distance FLOAT, station VARCHAR(200) NOT NULL, operator "
                     "VARCHAR(200) NOT NULL, clock VARCHAR(20) NOT NULL, software_version VARCHAR(40) NOT NULL, "
                     "reason TEXT NOT NULL)")  # no teardowns table either
        conn.execute("INSERT INTO tests VALUES (1, '/records/a', '2026-05-01T08:00:00+00:00', 'V1', 'S', "
                     "'p-edc-default', 'PE', 'PASS', 0.07, 0.004, 1.1, 1.2, 0.1, -0.2, 'st', 'ana', 'simulated', "
                     "'0.1.0', '')")
    with HistoryStore(f"sqlite:///{path}") as store:
        rows = store.list()
        assert len(rows) == 1 and rows[0].af_rel == 1.1 and rows[0].model_name is None
        assert rows[0].model_fits is None and rows[0].record_sha256 is None
        store.add_teardown("V1", "reusable", labelled_by="ana", labelled_at="2026-05-02")
        assert store.labelled_tests()[0].label == 0
        with store.engine.connect() as conn:
            assert migrate.current(conn) == migrate.head()
    with sqlite3.connect(path) as conn, pytest.raises(sqlite3.IntegrityError, match="append-only"):
        conn.execute("DELETE FROM tests")


@pytest.mark.slow  # the default suite's 5 minutes; CI's slow pass runs it
def test_label_command_records_lists_and_refuses_bad_input(tmp_path: Path) -> None:
    url = f"sqlite:///{tmp_path / 'h.sqlite'}"
    with HistoryStore(url) as store:
        store.add_row(_row("V/7", "2026-05-01T08:00:00+00:00", 1.4, 1.5, verdict="FAIL"))
    done = edc_bench("label", "V/7", "--finding", "worn", "--clearance-mm", "0.21", "--note", "scored plunger",
                     "--by", "ana", "--date", "2026-05-02", "--db", url)
    assert done.returncode == 0, done.stderr
    assert "labels the test of 2026-05-01 08:00 +00:00 (FAIL" in done.stdout
    listed = edc_bench("label", "--list", "--json", "--db", url)
    rows = json.loads(listed.stdout)
    assert [(r["valve_id"], r["finding"], r["labelled_by"], r["note"]) for r in rows] == \
        [("V/7", "worn", "ana", "scored plunger")]
    # a time with an offset is stored in UTC: 10:00+02:00 is 08:00 UTC, before the test of 09:00 UTC
    with HistoryStore(url) as store:
        store.add_row(_row("V/9", "2026-05-02T09:00:00+00:00", 1.1, 1.1))
    early = edc_bench("label", "V/9", "--finding", "reusable", "--date", "2026-05-02T10:00+02:00", "--db", url)
    assert early.returncode == 0 and "labels nothing" in early.stderr, early.stderr
    # a valve the history never saw: a mistyped id is refused; --new-valve records it all the same
    mistyped = edc_bench("label", "V/8", "--finding", "reusable", "--db", url)
    assert mistyped.returncode == 2 and "no test of valve 'V/8'" in mistyped.stderr, mistyped.stderr
    lonely = edc_bench("label", "V/8", "--finding", "reusable", "--new-valve", "--db", url)
    assert lonely.returncode == 0 and "labels nothing" in lonely.stderr
    for args, message in ((("V/7", "--finding", "worn", "--clearance-mm", "-0.1"), "--clearance-mm -0.1"),
                          (("V/7", "--finding", "worn", "--clearance-mm", "nan"), "--clearance-mm nan"),
                          (("V/7",), "--finding"),
                          (("V/7", "--finding", "worn", "--date", "yesterday"), "--date 'yesterday' is not a date"),
                          (("V/7", "--finding", "worn", "--date", "2999-01-01"), "in the future"),
                          (("V/7", "--finding", "worn", "--by", " "), "--by ' '"),
                          (("--delete", "12345"), "no teardown finding with id 12345")):
        bad = edc_bench("label", *args, "--db", url)
        assert bad.returncode == 2 and message in bad.stderr and "Traceback" not in bad.stderr, bad.stderr


def test_training_from_history_refuses_too_few_labels_saying_how_many(tmp_path: Path) -> None:
    url = f"sqlite:///{tmp_path / 'h.sqlite'}"
    with HistoryStore(url) as store:
        _synthetic_shop(store, 5)
    proc = edc_bench("train", "--from-history", "--db", url)
    assert proc.returncode == 2, proc.stderr
    assert "5 labelled test(s)" in proc.stderr and "at least 30" in proc.stderr and "edc-bench label" in proc.stderr
    assert "Traceback" not in proc.stderr


def test_labels_from_too_few_valves_are_refused_before_training() -> None:
    from edc_bench.learning.shop_training import check_enough

    labels = np.array([0, 1] * 20)
    with pytest.raises(ConfigError, match="from at least 5 different valves"):
        check_enough(labels, np.array([f"V{n % 4}" for n in range(40)]))  # 40 labels, 4 valves
    check_enough(labels, np.array([f"V{n}" for n in range(40)]))


def test_a_candidate_learns_the_shops_limit_and_is_adopted_explicitly(tmp_path: Path,
                                                                     monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("EDC_BENCH_DATA_DIR", str(tmp_path / "station"))
    with HistoryStore(f"sqlite:///{tmp_path / 'h.sqlite'}") as store:
        _synthetic_shop(store, 120)
        from edc_bench.history.labels import labelled_tests

        labelled = labelled_tests(store)
    assert len(labelled) == 120
    shipped = ValveClassifier()
    assert shipped.path == packaged_model_path()
    result = train_from_labels(labelled, None, shipped, prior_weight=0.0, seed=1)
    # the shipped model passes the valves between its limit and the shop's; the candidate, cross-validated, does not
    assert result.current.worn_passed > 10
    assert result.candidate_cv.accuracy > result.current.accuracy + 0.05
    candidate = tmp_path / "candidate.onnx"
    candidate.write_bytes(result.candidate.onnx_bytes)
    assert ValveClassifier().path == packaged_model_path()  # written is not adopted
    from edc_bench.learning.adoption import adopt, adopt_shipped

    adoption = adopt(candidate, "ana")
    station = ValveClassifier()
    assert station.name == result.name and station.sha256 == adoption["sha256"]
    assert default_classifier().sha256 == adoption["sha256"]
    # a changed adopted file is refused, not used
    adopted_file = Path(adoption["path"] if "path" in adoption else tmp_path / "station" / "models" / adoption["file"])
    original = adopted_file.read_bytes()
    adopted_file.write_bytes(original[:-1] + bytes([original[-1] ^ 1]))
    with pytest.raises(ConfigError, match="changed after it was adopted"):
        ValveClassifier()
    adopt(candidate, "ana")  # as the message says: adopting again restores it
    assert ValveClassifier().sha256 == adoption["sha256"]
    # a model whose name is a path stays inside the station's models folder
    from edc_bench.learning.train import fit_and_export

    odd = fit_and_export(labelled.features_rel, labelled.labels, "linear", 1,
                         metadata={"edc_bench.model_name": "../../escaped"})
    (tmp_path / "odd.onnx").write_bytes(odd.onnx_bytes)
    odd_adoption = adopt(tmp_path / "odd.onnx", "ana")
    assert (tmp_path / "station" / "models" / odd_adoption["file"]).is_file() and "/" not in odd_adoption["file"]
    adopt_shipped()
    assert ValveClassifier().path == packaged_model_path()


def test_an_adoption_keeps_in_the_history_what_it_was_decided_on(tmp_path: Path) -> None:
    from edc_bench.learning.candidate_evaluation import EVALUATION_KEY, CandidateEvaluation

    url = f"sqlite:///{tmp_path / 'h.sqlite'}"
    with HistoryStore(url) as store:
        _synthetic_shop(store, 60)
        from edc_bench.history.labels import labelled_tests

        labelled = labelled_tests(store)
    result = train_from_labels(labelled, None, ValveClassifier(), prior_weight=0.0, seed=1)
    candidate = tmp_path / "candidate.onnx"
    candidate.write_bytes(result.candidate.onnx_bytes)
    # the candidate's file carries the figures 'train --from-history' printed
    carried = CandidateEvaluation.from_json(ValveClassifier(candidate).metadata[EVALUATION_KEY])
    assert carried is not None and (carried.candidate, carried.replaced) == (result.candidate_cv, result.current)
    assert (carried.labels, carried.folds, carried.replaced_sha256) == (60, 5, ValveClassifier().sha256)
    env = {**__import__("os").environ, "EDC_BENCH_DATA_DIR": str(tmp_path / "station")}
    adopted = edc_bench("train", "--adopt", str(candidate), "--db", url, "--by", "ines", env=env)
    assert adopted.returncode == 0, adopted.stderr
    back = edc_bench("train", "--adopt", "shipped", "--db", url, "--by", "ines", env=env)
    assert back.returncode == 0, back.stderr
    with HistoryStore(url) as store:
        rows = store.adoptions()
    assert [CandidateEvaluation.from_json(r.evaluation) for r in rows] == [carried, None]  # shipped: none
    assert CandidateEvaluation.from_json('{"folds": "five"}') is None and CandidateEvaluation.from_json("[") is None


def test_the_labels_hash_names_the_data_a_candidate_learnt_from() -> None:
    a = LabelledTests(np.array([[1.0, 1.0]]), np.array([0]), np.array(["V"], dtype=object))
    b = LabelledTests(np.array([[1.0, 1.0]]), np.array([1]), np.array(["V"], dtype=object))
    assert a.content_hash() != b.content_hash()


def test_a_record_names_its_model_and_replays_with_it_after_the_station_changed_model(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from edc_bench.bench import run_simulated_test
    from edc_bench.config import load_variant, parse_variant
    from edc_bench.learning.adoption import adopt, adopt_shipped
    from edc_bench.records.record import write_record
    from edc_bench.replay import replay_record

    monkeypatch.setenv("EDC_BENCH_DATA_DIR", str(tmp_path / "station"))
    with HistoryStore(f"sqlite:///{tmp_path / 'h.sqlite'}") as store:
        _synthetic_shop(store, 60)
        from edc_bench.history.labels import labelled_tests

        result = train_from_labels(labelled_tests(store), None, ValveClassifier(), prior_weight=0.0, seed=1)
    candidate = tmp_path / "candidate.onnx"
    candidate.write_bytes(result.candidate.onnx_bytes)
    adoption = adopt(candidate, "ana")
    data = load_variant().model_dump()
    data["excitation"]["duration_s"] = 20.0  # long enough to converge, so the model judges
    test = run_simulated_test(parse_variant(data), "worn", 2, check_gains=False)
    assert test.classification.model_name == result.name
    assert test.classification.model_sha256 == adoption["sha256"]
    folder = write_record(test, tmp_path / "records", figure=False)
    with HistoryStore(f"sqlite:///{tmp_path / 'h.sqlite'}") as store:
        store.add(load_record(folder), folder)
        row = store.list()[-1]
    assert (row.model_name, row.model_sha256) == (result.name, adoption["sha256"])
    adopt_shipped()  # the station goes back; the record still replays with the model that judged it
    report = replay_record(folder)
    assert report.reproduced, report.differences
    assert report.judged.classification.model_sha256 == adoption["sha256"]


@pytest.mark.slow
def test_a_simulated_shop_with_a_stricter_scrap_limit_teaches_a_better_candidate(tmp_path: Path) -> None:
    # docs/diagnosis.md quotes these figures: 300 valves tested and torn down, the shipped simulated population
    # as prior (weight 50), 5-fold cross-validation on the shop's labels
    url = f"sqlite:///{tmp_path / 'shop.sqlite'}"
    env = {**__import__("os").environ, "EDC_BENCH_DATA_DIR": str(tmp_path / "station")}
    filled = __import__("subprocess").run(
        [__import__("sys").executable, "-m", "edc_bench.history.simulated_shop", "--db", url, "--count", "300"],
        capture_output=True, text=True, timeout=900, env=env)
    assert filled.returncode == 0, filled.stderr
    print(filled.stdout)
    proc = edc_bench("train", "--from-history", "--db", url, "--json", env=env, timeout=1800)
    assert proc.returncode == 0, proc.stderr
    figures = json.loads(proc.stdout)
    print(json.dumps(figures, indent=2))
    assert figures["labels"] >= 290
    candidate, current = figures["candidate"], figures["current"]
    assert candidate["accuracy"] >= current["accuracy"] + 0.05
    assert candidate["worn_passed"] < current["worn_passed"]
    assert candidate["reusable_failed"] <= current["reusable_failed"] + 3
    adopted = edc_bench("train", "--adopt", candidate["file"], env=env)
    assert adopted.returncode == 0, adopted.stderr
    judged = edc_bench("evaluate", "--from-history", "--db", url, "--json", env=env)
    assert judged.returncode == 0, judged.stderr
    assert json.loads(judged.stdout)["model"] == candidate["name"]
