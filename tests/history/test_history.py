"""The station's history: filters, trend, CSV, concurrent writers and aborts, on SQLite and PostgreSQL."""

from __future__ import annotations

import csv
import io
import json
import multiprocessing
import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

from edc_bench.history.rows import TestRow
from edc_bench.history.store import Filters, HistoryStore, write_csv
from edc_bench.records.reader import typed_record
from edc_bench.records.schema import Record


def _record(valve: str, started: str, verdict: str = "PASS", af: float = 0.07, a1: float = 0.0038,
            serial: str = "S-1", variant: str = "p-edc-default") -> Record:
    return typed_record({
        "verdict": verdict, "reasons": ["why"], "valve_id": valve, "variant": variant, "part_number": "PE-EDC-0001",
        "started_at": started, "clock": "simulated", "software_version": "0.1.0",
        "identity": {"pump_serial": serial, "station": "bench-3", "operator": "ana"},
        "features": {"af": af, "a1": a1},
        "classification": None if verdict == "INVALID" else {
            "verdict": verdict, "features_rel": {"af": af / 0.07, "a1": a1 / 0.0038}, "probability_faulty": 0.2,
            "distance": -0.3},
        "loop": {"abort_reason": "interrupted by the operator" if verdict == "INVALID" else None},
    }, "a test's record")


def test_filters_trend_and_csv(db_url: str, tmp_path: Path) -> None:
    with HistoryStore(db_url) as store:
        store.add(_record("V1", "2026-11-01T08:00:00+00:00"), tmp_path / "a")
        store.add(_record("V1", "2026-11-15T08:00:00+00:00", "FAIL", af=0.11, a1=0.007), tmp_path / "b")
        store.add(_record("V1", "2026-11-16T08:00:00+00:00", "INVALID"), tmp_path / "c")
        store.add(_record("V2", "2026-11-20T09:30:00+00:00", serial="S-2", variant="p-edc-long"), tmp_path / "d")
        # indexing a folder again: a new row, and the folder's newest row is the test as it stands
        store.add(_record("V2", "2026-11-20T09:30:00+00:00", serial="S-2", variant="p-edc-long"), tmp_path / "d")
        assert len(store.list()) == 4
        assert [r.verdict for r in store.list(Filters(valve_id="V1"))] == ["PASS", "FAIL", "INVALID"]
        assert [r.valve_id for r in store.list(Filters(pump_serial="S-2"))] == ["V2"]
        assert [r.valve_id for r in store.list(Filters(variant="p-edc-long"))] == ["V2"]
        assert len(store.list(Filters(variant="PE-EDC-0001"))) == 4  # by part number too
        assert [r.verdict for r in store.list(Filters(verdict="FAIL"))] == ["FAIL"]
        assert len(store.list(Filters(since="2026-11-15", until="2026-11-16"))) == 2  # the until day is included
        assert [r.started_at[:10] for r in store.list(limit=1)] == ["2026-11-20"]
        trend = store.trend("V1")  # trustworthy visits only, oldest first
        assert [r.verdict for r in trend] == ["PASS", "FAIL"]
        assert trend[1].af_rel == pytest.approx(0.11 / 0.07)
        invalid = store.list(Filters(verdict="INVALID"))[0]
        assert invalid.reason == "interrupted by the operator" and invalid.probability_faulty is None
        out = io.StringIO()
        assert write_csv(store.list(), out) == 4
    rows = list(csv.DictReader(io.StringIO(out.getvalue())))
    assert rows[0]["valve_id"] == "V1" and rows[0]["station"] == "bench-3" and rows[0]["operator"] == "ana"


def _writer(url: str, name: str, count: int, barrier: multiprocessing.synchronize.Barrier, folder: str) -> None:
    store = HistoryStore(url)
    barrier.wait()  # both start writing at the same moment
    for n in range(count):
        store.add(_record(f"{name}-{n}", f"2026-11-22T10:{n // 60:02d}:{n % 60:02d}+00:00"), Path(folder) / f"{name}{n}")
    store.close()


def test_concurrent_writers_all_land(db_url: str, tmp_path: Path) -> None:
    HistoryStore(db_url).close()
    ctx = multiprocessing.get_context("spawn")
    barrier = ctx.Barrier(2)
    procs = [ctx.Process(target=_writer, args=(db_url, name, 40, barrier, str(tmp_path))) for name in ("a", "b")]
    for p in procs:
        p.start()
    for p in procs:
        p.join(120)
        assert p.exitcode == 0
    with HistoryStore(db_url) as store:
        rows = store.list()
    assert len(rows) == 80
    assert len({r.record_dir for r in rows}) == 80


def _dies_in_transaction(url: str, folder: str) -> None:
    store = HistoryStore(url)
    conn = store.engine.connect()
    trans = conn.begin()
    from edc_bench.history.schema import tests
    from edc_bench.history.store import row_from_record

    conn.execute(tests.insert().values(**row_from_record(_record("ghost", "2026-11-22T11:00:00+00:00"),
                                                         Path(folder) / "ghost")))
    os._exit(1)  # killed before the commit (power cut, kill -9)
    trans.commit()


def test_a_writer_killed_mid_transaction_leaves_no_trace(db_url: str, tmp_path: Path) -> None:
    with HistoryStore(db_url) as store:
        store.add(_record("V1", "2026-11-22T09:00:00+00:00"), tmp_path / "kept")
    proc = multiprocessing.get_context("spawn").Process(target=_dies_in_transaction, args=(db_url, str(tmp_path)))
    proc.start()
    proc.join(60)
    assert proc.exitcode == 1
    with HistoryStore(db_url) as store:
        assert [r.valve_id for r in store.list()] == ["V1"]
        store.add(_record("V3", "2026-11-22T12:00:00+00:00"), tmp_path / "after")  # still writable
        assert len(store.list()) == 2


@pytest.mark.slow  # over 5 s each: the default suite's 5 minutes (CI's slow pass runs it)
def test_two_bench_tests_finishing_at_once_and_an_aborted_one_are_all_indexed(tmp_path: Path) -> None:
    url = f"sqlite:///{tmp_path / 'station.sqlite'}"
    env = {**os.environ, "EDC_BENCH_HISTORY_URL": url}
    base = [sys.executable, "-m", "edc_bench", "test", "--no-figure", "--json", "--out", str(tmp_path / "records")]
    procs = [subprocess.Popen([*base, "--valve", valve, "--valve-id", f"V-{valve}", "--pump-serial", "P-77"],
                              env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
             for valve in ("new", "worn")]
    # and one stopped by the operator (SIGINT) half-way: INVALID, indexed all the same (full length: stopped early
    # at 10 s, "verdict certain", it could end before the signal came)
    interrupted = subprocess.Popen([*base, "--valve", "new", "--valve-id", "V-stopped", "--duration-s", "600",
                                    "--full-length"],
                                   env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    outs = [p.communicate(timeout=300) for p in procs]
    assert [p.returncode for p in procs] == [0, 11], [o[1] for o in outs]
    # its CAN log is streamed from the moment its loop starts: then Ctrl-C is the operator's stop
    deadline = time.monotonic() + 120
    while not list((tmp_path / "records").glob("*V-stopped*/can.log")):
        assert time.monotonic() < deadline and interrupted.poll() is None, "the long test never started"
        time.sleep(0.05)
    interrupted.send_signal(2)
    out, err = interrupted.communicate(timeout=120)
    assert interrupted.returncode == 130, err  # interrupted (README's exit codes); the record says INVALID
    assert json.loads(out)["verdict"] == "INVALID"
    with HistoryStore(url) as store:
        rows = {r.valve_id: r for r in store.list()}
    assert set(rows) == {"V-new", "V-worn", "V-stopped"}
    assert rows["V-new"].verdict == "PASS" and rows["V-worn"].verdict == "FAIL"
    assert rows["V-worn"].pump_serial == "P-77"
    assert rows["V-stopped"].verdict == "INVALID" and "interrupted" in rows["V-stopped"].reason
    # how each went: coil, model fit, when and why it stopped
    for name in ("V-new", "V-worn"):
        assert rows[name].coil_in_spec is True and rows[name].coil_r20_ohm == pytest.approx(0.7, rel=0.1)
        assert rows[name].model_fits is True
        assert rows[name].stop_reason == "verdict certain" and rows[name].test_s == pytest.approx(10.0, abs=0.1)
    assert rows["V-stopped"].stop_reason == "aborted" and 0 < rows["V-stopped"].test_s < 600
    assert (tmp_path / "station.sqlite-wal").exists() or (tmp_path / "station.sqlite").exists()


def test_history_command(tmp_path: Path) -> None:
    url = f"sqlite:///{tmp_path / 'h.sqlite'}"
    with HistoryStore(url) as store:
        store.add(_record("V1", "2026-11-01T08:00:00+00:00"), tmp_path / "a")
        store.add(_record("V1", "2026-11-15T08:00:00+00:00", "FAIL", af=0.11, a1=0.007), tmp_path / "b")
    cmd = [sys.executable, "-m", "edc_bench", "history", "--db", url]
    listing = subprocess.run([*cmd, "--valve", "V1"], capture_output=True, text=True, timeout=120)
    assert listing.returncode == 0 and "2 test(s)" in listing.stdout and "FAIL" in listing.stdout
    trend = subprocess.run([*cmd, "--trend", "V1", "--plot", str(tmp_path / "t.png")], capture_output=True, text=True,
                           timeout=120)
    assert trend.returncode == 0 and "+57.1%" in trend.stdout  # 0.11 / 0.07
    assert (tmp_path / "t.png").read_bytes()[:4] == b"\x89PNG"
    export = subprocess.run([*cmd, "--csv", str(tmp_path / "out.csv"), "--verdict", "fail"], capture_output=True,
                            text=True, timeout=120)
    assert export.returncode == 0
    assert len(list(csv.DictReader((tmp_path / "out.csv").open()))) == 1
    for args, message in ((["--since", "22/11/2026"], "is not a date"), (["--trend", "nobody"], "no trustworthy test"),
                          (["--plot", "x.png"], "--trend"), (["--csv", str(tmp_path / "no" / "x.csv")], "does not exist")):
        proc = subprocess.run([*cmd, *args], capture_output=True, text=True, timeout=120)
        assert proc.returncode == 2 and message in proc.stderr and "Traceback" not in proc.stderr, proc.stderr
    bad = subprocess.run([sys.executable, "-m", "edc_bench", "history", "--db", "nonsense"], capture_output=True,
                         text=True, timeout=120)
    assert bad.returncode == 2 and "not a database URL" in bad.stderr


def test_a_pump_the_model_does_not_fit_is_kept_as_such(tmp_path: Path) -> None:
    """The history says which tests the model did not fit (so the shop can find a pump that needs its own variant)."""
    from edc_bench.bench import run_simulated_test
    from edc_bench.config import load_variant, parse_variant
    from edc_bench.history.store import row_from_record
    from edc_bench.records.reader import load_record
    from edc_bench.records.record import write_record

    data = load_variant("p-edc-hard").model_dump()
    data["coil"]["force_constant_variation_per_mm"] = 0.0667  # +/-30 % over the swing
    data["pump"]["name"] = "gain-test"
    result = run_simulated_test(parse_variant(data), "worn", 0, nominal_baseline=True)
    folder = write_record(result, tmp_path, figure=False)
    row = row_from_record(load_record(folder), folder)
    assert row["verdict"] == "INVALID" and row["model_fits"] is False
    assert row["stop_reason"] == "model does not fit" and row["test_s"] < 30.0
    assert row["reason"].startswith("the feedforward model does not fit this pump")
    # a record without those sections (hand-edited, or older) leaves them empty
    bare = row_from_record(typed_record({"verdict": "PASS", "identification": {"model_fit": None}}, "bare"), folder)
    assert [bare[k] for k in ("coil_r20_ohm", "coil_in_spec", "model_fits", "stop_reason", "test_s")] == [None] * 5


def test_csv_export_never_hands_a_spreadsheet_a_formula(tmp_path: Path) -> None:
    """An id typed as '=HYPERLINK(...)' (or starting +, -, @) is exported as text; numbers stay numbers."""
    shown = {"valve_id": '=HYPERLINK("http://x","open")', "pump_serial": "+41", "operator": "@ana",
             "station": "-bay 2", "af_rel": -0.25, "distance": -0.6, "reason": "plain text"}
    row = TestRow(id=1, record_dir="/records/r1", started_at="2026-11-27T08:00:00+00:00", variant="p-edc-default",
                  part_number="PE", verdict="PASS", clock="simulated", software_version="0.1.0", **shown)
    out = io.StringIO()
    write_csv([row], out, columns=list(shown))
    (read,) = csv.DictReader(io.StringIO(out.getvalue()))
    assert read == {"valve_id": '\'=HYPERLINK("http://x","open")', "pump_serial": "'+41", "operator": "'@ana",
                    "station": "'-bay 2", "af_rel": "-0.25", "distance": "-0.6", "reason": "plain text"}


@pytest.mark.parametrize("text", ["sqlite:///h.sqlite", "sqlite:////abs/h.sqlite", "sqlite:///a b.sqlite",
                                  "sqlite:///./x/../h.db", "sqlite:///~/h.db", "sqlite:///a@b.db",
                                  "sqlite:///u:p@h.db", "sqlite:///a:b.db", "sqlite:///a+b;c=d.db",
                                  "sqlite:///a%20b.db", "sqlite:///h.db?mode=ro", "sqlite:///h.db#x",
                                  "sqlite:///:memory:", "sqlite://", "postgresql+psycopg://u@h/db"])
def test_a_plain_sqlite_url_names_the_file_sqlalchemy_would_open(text: str) -> None:
    """The check before a test reads sqlite:///FILE without SQLAlchemy: it must name SQLAlchemy's file, or leave
    the URL to SQLAlchemy (escapes, options, memory, other databases)."""
    import sqlalchemy as sa

    from edc_bench.history.url import plain_sqlite_path

    path, url = plain_sqlite_path(text), sa.engine.make_url(text)
    if url.get_backend_name() != "sqlite" or set("%?#") & set(text) or url.database in (None, "", ":memory:"):
        assert path is None
    else:
        assert path == Path(url.database)


@pytest.mark.parametrize("kept", [
    [{"table": "tests", "id": True, "row_hash": "a" * 64}],  # JSON's true is no row's id
    [{"table": "tests", "id": 2**70, "row_hash": "a" * 64}],  # beyond any id column (was an internal error)
    [{"table": "tests", "id": "1", "row_hash": "a" * 64}],
    [{"table": "tests", "row_hash": "a" * 64}],
    {"table": "tests", "id": 1, "row_hash": "a" * 64},
], ids=["bool-id", "huge-id", "text-id", "no-id", "not-a-list"])
def test_verify_refuses_a_kept_heads_file_that_is_not_what_heads_writes(tmp_path: Path, kept: object) -> None:
    url = f"sqlite:///{tmp_path / 'h.sqlite'}"
    with HistoryStore(url) as store:
        store.add(_record("V1", "2026-11-01T08:00:00+00:00"), tmp_path / "a")
    heads = tmp_path / "heads.json"
    heads.write_text(json.dumps(kept), encoding="utf-8")
    from helpers import edc_bench

    found = edc_bench("history", "--verify", "--heads", str(heads), "--db", url)
    assert found.returncode == 2, found.stderr
    assert "not the JSON 'edc-bench history --heads' writes" in found.stderr and "Traceback" not in found.stderr
