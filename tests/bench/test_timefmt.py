"""Times as people read them (edc_bench.timefmt): local with the offset; the history and records keep UTC.

A technician in Berlin found `history`, `history --rig`, `rig-selfcheck` and the session's NO-GO prompt in UTC while
the session and reports gave local time, and record folders named in UTC beside a shift file in local time.
"""

from __future__ import annotations

import datetime as dt
import json
import os
import sys
from pathlib import Path

import pytest
from helpers import edc_bench

from edc_bench.history.schema import COLUMNS
from edc_bench.history.store import HistoryStore
from edc_bench.timefmt import folder_stamp, local_column, local_text, parse_local_input, parse_stored

BERLIN = "CET-1CEST,M3.5.0,M10.5.0/3"  # POSIX TZ: Central European time, summer time from March to October


def test_a_stored_time_reads_in_local_time_with_its_offset(time_zone) -> None:
    time_zone(BERLIN)
    assert local_text("2026-11-26T10:04:00+00:00") == "2026-11-26 11:04 +01:00"
    assert local_text("2026-07-26T10:04:00+00:00") == "2026-07-26 12:04 +02:00"  # summer time
    assert local_text("2026-11-26T10:04:05", seconds=True) == "2026-11-26 11:04:05 +01:00"  # no offset stored: UTC
    assert local_text("2026-11-26") == "2026-11-26"  # a date alone has no time of day to move
    assert local_text(None, empty="-") == "-" and local_text("not a time") == "not a time"
    time_zone("IST-5:30")
    assert local_text("2026-11-26T10:04:00+00:00") == "2026-11-26 15:34 +05:30"


def test_a_table_column_says_its_offset_once_unless_summer_time_changes_within_it(time_zone) -> None:
    time_zone(BERLIN)
    cells, note = local_column(["2026-11-26T10:04:00+00:00", "2026-11-27T08:00:00+00:00", None])
    assert cells == ["2026-11-26 11:04", "2026-11-27 09:00", ""] and note == "local time, UTC+01:00"
    cells, note = local_column(["2026-10-24T10:00:00+00:00", "2026-10-26T10:00:00+00:00"])
    assert cells == ["2026-10-24 12:00 +02:00", "2026-10-26 11:00 +01:00"] and note == "local time"


def test_record_folders_are_named_in_local_time_with_the_offset(time_zone) -> None:
    time_zone(BERLIN)
    assert folder_stamp("2026-11-26T10:04:00+00:00") == "20261126T110400+0100"
    time_zone("EST+5")
    assert folder_stamp("2026-11-26T10:04:00+00:00") == "20261126T050400-0500"


def test_a_typed_time_is_local_unless_it_gives_an_offset(time_zone) -> None:
    time_zone(BERLIN)
    assert parse_local_input("2026-11-26T11:04") == dt.datetime(2026, 11, 26, 10, 4, tzinfo=dt.UTC)
    assert parse_local_input("2026-11-26T11:04+00:00") == dt.datetime(2026, 11, 26, 11, 4, tzinfo=dt.UTC)
    assert parse_stored("2026-11-26T10:04:00") == dt.datetime(2026, 11, 26, 10, 4, tzinfo=dt.UTC)


def _row(valve: str, started: str) -> dict:
    row = {name: "" for name in COLUMNS if name not in ("id", "record_sha256", "indexed_at", "indexed_by")}
    row.update(record_dir=f"/records/{valve}", started_at=started, valve_id=valve, verdict="PASS", af_v=None,
               a1_v_s_per_mm=None, af_rel=1.0, a1_rel=1.0, probability_faulty=None, distance=None, model_name=None,
               model_sha256=None, coil_r20_ohm=None, coil_in_spec=None, model_fits=None, stop_reason=None,
               test_s=None, simulated=None)
    return row


def test_history_listings_and_a_teardowns_time_are_local_as_a_technician_in_berlin_reads_them(tmp_path: Path) -> None:
    url = f"sqlite:///{tmp_path / 'h.sqlite'}"
    with HistoryStore(url) as store:
        store.add_row(_row("V1", "2026-11-26T10:04:00+00:00"))
    env = {**os.environ, "TZ": BERLIN, "COLUMNS": "200"}
    listing = edc_bench("history", "--db", url, env=env)
    assert listing.returncode == 0, listing.stderr
    shown = " ".join(listing.stdout.split())  # the title wraps with the temporary path's length
    assert "2026-11-26 11:04" in shown and "(local time, UTC+01:00)" in shown, listing.stdout
    assert "UTC)" not in shown.replace("UTC+01:00)", "")
    trend = " ".join(edc_bench("history", "--trend", "V1", "--db", url, env=env).stdout.split())
    assert "2026-11-26 11:04" in trend and "(local time, UTC+01:00)" in trend, trend
    # a teardown at 14:00 typed in Berlin is 13:00 UTC in the history, and reads 14:00 +01:00 again
    done = edc_bench("label", "V1", "--finding", "reusable", "--by", "ana", "--date", "2026-11-26T14:00", "--db",
                     url, env=env)
    assert done.returncode == 0, done.stderr
    assert "labels the test of 2026-11-26 11:04 +01:00" in done.stdout, done.stdout
    with HistoryStore(url) as store:
        assert [r.labelled_at for r in store.teardowns()] == ["2026-11-26T13:00:00+00:00"]
    audit = edc_bench("history", "--audit", "V1", "--db", url, env=env)
    assert audit.returncode == 0, audit.stderr
    written = " ".join(audit.stdout.split())
    assert "tested 2026-11-26 11:04 +01:00" in written and "opened 2026-11-26 14:00 +01:00" in written, audit.stdout


@pytest.mark.skipif(sys.platform == "win32", reason="POSIX TZ strings")
def test_a_records_folder_is_named_in_the_local_time_of_the_test(tmp_path: Path) -> None:
    proc = edc_bench("test", "--valve", "new", "--no-figure", "--no-history", "--out", str(tmp_path), "--json",
                     env={**os.environ, "TZ": "IST-5:30"})
    assert proc.returncode == 0, proc.stderr
    (folder,) = tmp_path.iterdir()

    started = dt.datetime.fromisoformat(json.loads((folder / "record.json").read_text())["started_at"])
    assert started.utcoffset() == dt.timedelta(0)  # record.json keeps UTC
    local = started.astimezone(dt.timezone(dt.timedelta(hours=5, minutes=30)))
    assert folder.name.startswith(f"{local:%Y%m%dT%H%M%S}+0530-"), folder.name


def test_history_since_and_until_are_local_days_as_the_listing_shows_them(tmp_path: Path) -> None:
    """A test at 00:30 on 27 November in Berlin (23:30 UTC on the 26th) is listed on the 27th: `--since 2026-11-27`
    finds it and `--until 2026-11-26` does not (a review found the days compared in UTC)."""
    url = f"sqlite:///{tmp_path / 'h.sqlite'}"
    with HistoryStore(url) as store:
        store.add_row(_row("V1", "2026-11-26T23:30:00+00:00"))
    env = {**os.environ, "TZ": BERLIN}
    since = edc_bench("history", "--since", "2026-11-27", "--json", "--db", url, env=env)
    until = edc_bench("history", "--until", "2026-11-26", "--json", "--db", url, env=env)
    assert [r["valve_id"] for r in json.loads(since.stdout)] == ["V1"], since.stderr
    assert json.loads(until.stdout) == [], until.stderr
    at = edc_bench("history", "--since", "2026-11-27T00:00+01:00", "--until", "2026-11-27T01:00", "--json", "--db",
                   url, env=env)
    assert [r["valve_id"] for r in json.loads(at.stdout)] == ["V1"], at.stderr
