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


def test_the_workshop_typed_once_is_kept_in_the_settings_with_what_they_held(tmp_path: Path) -> None:
    """The session asks for the workshop once (``workshop_asked`` false until it is written, even as ""); writing it
    keeps the settings' other keys and comments, and a value the settings would refuse is refused before."""
    import pytest

    from edc_bench.errors import ConfigError
    from edc_bench.station_settings import StationIdentity, remember_workshop, station_identity, workshop_asked

    data = tmp_path / "station-data"
    assert not workshop_asked(data)
    remember_workshop("", "", data)  # Enter alone in both: asked, and none printed
    assert workshop_asked(data) and station_identity(data).shop == ""
    (data / "station.toml").write_text('# bench 2\n[station]\nname = "Bench 2"  # hall B\n\n[scan]\n'
                                       "valve_id = 'V-\\d{5}'\n", encoding="utf-8")
    assert not workshop_asked(data)
    remember_workshop("Diesel Müller GmbH", "Hauptstraße 5, 80331 München", data)
    text = (data / "station.toml").read_text(encoding="utf-8")
    assert "# bench 2" in text and "# hall B" in text and "valve_id = 'V-\\d{5}'" in text
    assert station_identity(data) == StationIdentity(name="Bench 2", shop="Diesel Müller GmbH",
                                                     shop_address="Hauptstraße 5, 80331 München")
    with pytest.raises(ConfigError, match="at most 100 printable characters"):
        remember_workshop("x" * 101, "", data)


def test_the_session_asks_for_the_workshop_once_after_the_operator(tmp_path: Path, monkeypatch) -> None:
    """Where the station's settings name no workshop, the session asks for its name and address (at 80x24, each
    instruction whole) before the shift's first prompt, and keeps them; the next session does not ask."""
    import asyncio

    from edc_bench.session.build import make_app
    from edc_bench.session.runner import RigChoice
    from edc_bench.station_settings import station_identity, workshop_asked

    data = tmp_path / "station-data"
    monkeypatch.setenv("EDC_BENCH_DATA_DIR", str(data))

    async def session() -> tuple[str, str, str]:
        app = make_app(None, RigChoice(), tmp_path / "records", f"sqlite:///{tmp_path / 'h.sqlite'}", "bench-1", "",
                       ask_workshop=not workshop_asked())
        async with app.run_test(size=(80, 24)) as pilot:
            await pilot.pause()
            await pilot.press(*"Jo", "enter")  # the operator first
            await pilot.pause()
            asked = " ".join(str(w.render()) for w in app.screen.query("Label"))
            # typed at once after the name's Enter, as a fast typist or a scanner does: the address whole
            await pilot.press(*"Diesel Müller GmbH", "enter", *"Hauptstraße 5, 80331 München")
            asked += " " + " ".join(str(w.render()) for w in app.screen.query("Label"))
            await pilot.press("enter")
            await pilot.pause()
            asked += " " + " ".join(str(w.render()) for w in app.screen.query("Label"))
            await pilot.press(*"Bench 2", "enter")  # the settings name no station: its name for the customer's page
            await pilot.pause()
            prompt = str(app.query_one("#prompt").render())
            message = app.message
            await pilot.press("ctrl+q", "ctrl+q")
        return asked, prompt, message

    asked, prompt, message = asyncio.run(session())
    assert "Type the WORKSHOP's NAME, then Enter (Enter alone: none)" in asked
    assert "ADDRESS on one line, then Enter" in asked
    assert prompt == "Scan or type the VALVE ID, then Enter"
    assert "workshop kept in" in message
    assert station_identity(data).shop == "Diesel Müller GmbH"
    assert station_identity(data).shop_address == "Hauptstraße 5, 80331 München"
    assert "this BENCH's NAME as the reports print it" in asked
    assert station_identity(data).shown_name == "Bench 2" and station_identity(data).name == ""
    assert workshop_asked()


def test_enter_pressed_fast_at_the_workshop_question_takes_none_and_never_fails(tmp_path: Path, monkeypatch) -> None:
    """Four Enters in one burst (Enter alone at each of the three questions, and one more queued while the screen
    closes, as a scanner's CR LF gives): no workshop is printed, the session goes on (the last once raised
    IndexError)."""
    import asyncio

    from edc_bench.session.build import make_app
    from edc_bench.session.runner import RigChoice
    from edc_bench.station_settings import station_identity, workshop_asked

    data = tmp_path / "station-data"
    monkeypatch.setenv("EDC_BENCH_DATA_DIR", str(data))

    async def session() -> str:
        app = make_app(None, RigChoice(), tmp_path / "records", f"sqlite:///{tmp_path / 'h.sqlite'}", "bench-1", "Jo",
                       ask_workshop=True)
        async with app.run_test(size=(80, 24)) as pilot:
            await pilot.pause()
            from textual.widgets import Input

            line = app.screen.query_one("#workshop-line", Input)
            for _ in range(4):  # queued together, as a burst of keys is, before the screen can close
                line.post_message(Input.Submitted(line, ""))
            await pilot.pause()
            await pilot.pause()
            prompt = str(app.query_one("#prompt").render())
            await pilot.press("ctrl+q", "ctrl+q")
        return prompt

    assert asyncio.run(session()) == "Scan or type the VALVE ID, then Enter"
    assert workshop_asked(data) and station_identity(data).shop == ""


def test_the_customers_page_never_prints_the_pcs_host_name(tmp_path: Path, monkeypatch) -> None:
    """The tester's finding: page 1 said "Station vm" (the PC's host name) when the shop had named its station
    nowhere. Unnamed: no station row; a name for customers ([station] shown_name) or --station: that name."""
    import socket

    from edc_bench.cli import main
    from edc_bench.records.reader import load_record
    from edc_bench.records.report_content import test_rows

    data = tmp_path / "station-data"
    monkeypatch.setenv("EDC_BENCH_DATA_DIR", str(data))

    def page_rows(*flags: str) -> dict[str, str]:
        out = tmp_path / f"records-{len(list(tmp_path.iterdir()))}"
        assert main(["test", "--no-history", "--no-figure", "--plain", "--out", str(out), *flags]) == 0
        (folder,) = out.iterdir()
        return dict(test_rows(load_record(folder)))

    unnamed = page_rows()
    assert "Station" not in unnamed and socket.gethostname() not in unnamed.values()
    assert page_rows("--station", "S-4")["Station"] == "S-4"
    data.mkdir(exist_ok=True)
    (data / "station.toml").write_text('[station]\nshown_name = "Bench 2"\n', encoding="utf-8")
    assert page_rows()["Station"] == "Bench 2"
    # a record from before the field (station_shown absent) prints its station as it did
    from edc_bench.records.schema import Record

    older = Record.model_validate({"verdict": "PASS", "identity": {"station": "bench-pc"}})
    assert dict(test_rows(older))["Station"] == "bench-pc"
