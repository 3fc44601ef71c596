"""The customer's page names the workshop and the station as the shop set them (#53 item 8): before, page 1 named
the station by the PC's host name ("vm") and had no workshop name or address."""

from __future__ import annotations

import json
import os
import socket
from pathlib import Path

from helpers import edc_bench

from edc_bench.records.reader import load_record, load_trace
from edc_bench.records.report import report_pages

SETTINGS = """[station]
name = "Bench 2 (hall B)"
shop = "Diesel Müller GmbH"
shop_address = "Hauptstraße 5\\n80331 München"
"""


def test_the_station_and_workshop_set_once_name_every_record_and_page_1(tmp_path: Path) -> None:
    data = tmp_path / "station-data"
    data.mkdir()
    (data / "station.toml").write_text(SETTINGS, encoding="utf-8")
    env = {**os.environ, "EDC_BENCH_DATA_DIR": str(data)}
    proc = edc_bench("test", "--valve", "worn", "--no-figure", "--no-history", "--json", "--out", str(tmp_path / "r"),
                     env=env)
    assert proc.returncode == 11, proc.stderr
    (folder,) = (tmp_path / "r").iterdir()
    record = load_record(folder)
    assert (record.identity.station, record.identity.shop) == ("Bench 2 (hall B)", "Diesel Müller GmbH")
    assert record.identity.shop_address == "Hauptstraße 5\n80331 München"
    page = report_pages(record, load_trace(folder), folder.name)[0]
    text = " ".join(" ".join(t.get_text().split()) for t in page.figure.texts)
    assert "Workshop" in text and "Diesel Müller GmbH, Hauptstraße 5, 80331 München" in text, text
    assert "Bench 2 (hall B)" in text
    assert f" {socket.gethostname()} " not in f" {text} "  # the PC's name is no station's name here
    assert json.loads(proc.stdout)["verdict"] == "FAIL"


def test_a_station_setting_that_cannot_be_used_is_refused_naming_the_file_and_key(tmp_path: Path) -> None:
    data = tmp_path / "station-data"
    data.mkdir()
    env = {**os.environ, "EDC_BENCH_DATA_DIR": str(data)}
    for text, said in (('[station]\nshopname = "x"\n', "[station] has no key 'shopname'"),
                       ('[station]\nshop = 5\n', "[station] shop must be text"),
                       ('[station]\nname = "a\\u0007b"\n', "[station] name must be text"),
                       ('[station]\nname = "bench\\n2"\n', "[station] name must be text")):  # lines: the address only
        (data / "station.toml").write_text(text, encoding="utf-8")
        proc = edc_bench("test", "--valve", "new", "--no-figure", "--no-history", "--out", str(tmp_path / "r"),
                         env=env)
        assert proc.returncode == 2, (text, proc.stderr)
        assert said in proc.stderr and str(data / "station.toml") in proc.stderr, proc.stderr
        assert "Traceback" not in proc.stderr
