"""The web view's pages over HTTP, as a browser and an attacker use them (Starlette's test client, in process):
sign-in, sessions, CSRF, the security headers, the figures against ``history --summary``, escaping, every filter
and search field fed SQL, report paths outside the records folder."""

from __future__ import annotations

import html
import json
import re
from pathlib import Path

import pytest
from markupsafe import escape
from web_site import TOKEN, FakeClock, signed_in
from starlette.testclient import TestClient

from edc_bench.cli import main
from edc_bench.history.demo_chain import ODD_VALVE_IDS
from edc_bench.history.store import Filters, HistoryStore
from edc_bench.history.summary import chain_summary
from edc_bench.web.app import CSP

PAGES = ("/chain", "/rigs", "/valves?q=V-08", "/valve?id=V-0815", "/models", "/chain/verdicts.csv", "/rigs.csv",
         "/valve.csv?id=V-0815", "/models.csv", "/report/1")


@pytest.mark.parametrize("path", PAGES)
def test_a_page_without_a_session_redirects_to_sign_in(client: TestClient, path: str) -> None:
    response = client.get(path)
    assert response.status_code == 303
    assert response.headers["location"].startswith("/signin?next=%2F")


def test_sign_in_sets_a_secure_http_only_session_cookie_and_reaches_every_page(client: TestClient) -> None:
    form = client.get("/signin")
    csrf = re.search(r'name="csrf" value="([^"]+)"', form.text).group(1)  # type: ignore[union-attr]
    response = client.post("/signin", data={"csrf": csrf, "login": "ana", "password": TOKEN, "next": "/rigs"})
    assert response.status_code == 303 and response.headers["location"] == "/rigs"
    cookie = response.headers["set-cookie"].lower()
    assert "edc_session=" in cookie and "httponly" in cookie and "secure" in cookie and "samesite=strict" in cookie
    for path in PAGES[:-1]:
        page = client.get(path)
        assert page.status_code == 200, (path, page.text[:300])


@pytest.mark.parametrize("form", [
    {"login": "ana", "password": TOKEN},  # no CSRF token at all
    {"login": "ana", "password": TOKEN, "csrf": "forged-token-of-another-page"},
    {"login": "ana", "password": TOKEN, "csrf": "Prüfstand-token"},  # not ASCII: compared as bytes, no error
])
def test_a_sign_in_posted_without_its_csrf_token_is_refused(client: TestClient, form: dict[str, str]) -> None:
    client.get("/signin")  # the browser has the sign-in cookie; the attacker's page posts without the form's token
    response = client.post("/signin", data=form)
    assert response.status_code == 403
    assert "did not come from this page" in response.text
    assert "edc_session" not in response.headers.get("set-cookie", "")


def test_a_wrong_access_token_is_refused(client: TestClient) -> None:
    form = client.get("/signin")
    csrf = re.search(r'name="csrf" value="([^"]+)"', form.text).group(1)  # type: ignore[union-attr]
    response = client.post("/signin", data={"csrf": csrf, "login": "ana", "password": "guess"})
    assert response.status_code == 403 and "wrong access token" in response.text


def test_sign_out_needs_its_csrf_token_and_ends_the_session(client: TestClient) -> None:
    signed_in(client)
    refused = client.post("/signout", data={"csrf": "not-the-token"})
    assert refused.status_code == 403
    assert client.get("/chain").status_code == 200  # still signed in
    token = re.search(r'name="csrf" value="([^"]+)"', client.get("/chain").text).group(1)  # type: ignore[union-attr]
    assert client.post("/signout", data={"csrf": token}).status_code == 303
    assert client.get("/chain").status_code == 303


def test_a_session_expires_after_its_idle_time(client: TestClient, clock: FakeClock) -> None:
    signed_in(client)
    clock.now_s += 25 * 60
    assert client.get("/chain").status_code == 200  # a page within the idle time renews it
    clock.now_s += 31 * 60
    assert client.get("/chain").status_code == 303


def test_sign_in_never_redirects_to_another_host(client: TestClient) -> None:
    for target in ("//evil.example/", "https://evil.example/", "/\\evil.example", "/chain\r\nSet-Cookie: x=1"):
        form = client.get("/signin", params={"next": target})
        csrf = re.search(r'name="csrf" value="([^"]+)"', form.text).group(1)  # type: ignore[union-attr]
        response = client.post("/signin", data={"csrf": csrf, "login": "ana", "password": TOKEN, "next": target})
        assert response.headers["location"] == "/chain", target


@pytest.mark.parametrize("path", ["/signin", *PAGES[:5]])
def test_every_page_carries_a_content_security_policy_and_no_script(client: TestClient, path: str) -> None:
    if path != "/signin":
        signed_in(client)
    response = client.get(path)
    assert response.headers["content-security-policy"] == CSP
    assert "script-src" not in CSP and "default-src 'none'" in CSP
    assert response.headers["x-content-type-options"] == "nosniff"
    assert "<script" not in response.text.lower().replace("&lt;script", "")


def _figure(page: str, name: str) -> str:
    found = re.search(rf'id="{name}">([^<]*)<', page)
    assert found is not None, name
    return found.group(1)


def test_the_chain_page_shows_the_figures_history_summary_prints(client: TestClient, demo_db: Path,
                                                                 capsys: pytest.CaptureFixture[str]) -> None:
    signed_in(client)
    page = client.get("/chain", params={"station": "Werkstatt Nord 1", "since": ""}).text  # all days
    assert main(["history", "--db", f"sqlite:///{demo_db}", "--summary", "--station", "Werkstatt Nord 1",
                 "--json"]) == 0
    printed = json.loads(capsys.readouterr().out)
    assert int(_figure(page, "tests")) == printed["tests"] > 50
    assert _figure(page, "first-pass") == f"{printed['first_pass_rate'] * 100:.1f} %"
    assert _figure(page, "marginal") == f"{printed['marginal_rate'] * 100:.1f} %"
    for verdict, count in printed["verdicts"]:
        assert re.search(rf'{verdict}</td><td class="num">{count}</td>', page), verdict
    for area, count in printed["invalid_areas"]:
        assert f"<td>{html.escape(area)}</td><td class=\"num\">{count}</td>" in page


def test_the_chain_page_names_the_quiet_station(client: TestClient) -> None:
    signed_in(client)
    page = client.get("/chain").text
    quiet = re.findall(r'<tr class="quiet"><td>([^<]+)</td>', page)
    assert quiet == ["Werkstatt West 4"]


def test_a_day_that_is_no_date_is_said_on_the_page(client: TestClient) -> None:
    signed_in(client)
    response = client.get("/chain?since=yesterday")
    assert response.status_code == 400
    assert "is not a date: write it as YYYY-MM-DD" in response.text
    for far in ("since=0001-01-01", "until=9999-12-31", "until=9999-12-31T23:59:59%2B00:00"):  # no day after it
        response = client.get(f"/chain?{far}")
        assert response.status_code == 400 and "give a year from 1900 to 9000" in response.text, far


SQL = ("' OR '1'='1", "x'; DROP TABLE tests; --", "\" OR 1=1 --", "%", "_", "V-0815' UNION SELECT * FROM edc_logins --",
       "1) OR (1=1")


@pytest.mark.parametrize("text", SQL)
def test_sql_in_every_filter_and_search_field_changes_nothing(client: TestClient, demo_db: Path, text: str) -> None:
    signed_in(client)
    for field in ("station", "pump", "technician"):
        response = client.get("/chain", params={field: text})
        assert response.status_code == 200, (field, response.text[:300])
        assert _figure(response.text, "tests") == "0", field
    for field in ("since", "until"):
        response = client.get("/chain", params={field: text})
        assert response.status_code == 400 and "is not a date" in response.text
    search = client.get("/valves", params={"q": text})
    assert search.status_code == 200 and "No valve or pump begins with" in search.text
    valve = client.get("/valve", params={"id": text})
    assert valve.status_code == 200 and "No test of this valve stands." in valve.text
    with HistoryStore(f"sqlite:///{demo_db}", must_exist=True) as store:
        assert chain_summary(store, Filters()).tests > 300  # nothing was dropped


def test_a_valve_id_holding_script_and_quotes_is_shown_as_text(client: TestClient) -> None:
    signed_in(client)
    for valve in ODD_VALVE_IDS:
        page = client.get("/valve", params={"id": valve}).text
        assert str(escape(valve)) in page and "No test of this valve stands." not in page
        assert "<script>alert" not in page
    found = client.get("/valves", params={"q": "V-<"}).text
    assert str(escape(ODD_VALVE_IDS[0])) in found and "<script>alert" not in found
    operators = client.get("/valve", params={"id": ODD_VALVE_IDS[2]}).text
    assert "jonas &lt;j@shop&gt;" in operators


def test_a_valve_page_shows_its_visits_trend_and_what_was_withdrawn_or_changed(client: TestClient) -> None:
    signed_in(client)
    story = client.get("/valve", params={"id": "V-0815"}).text
    decisions = re.findall(r'<td class="verdict (\w+)">', story)
    assert decisions == ["PASS", "PASS", "MARGINAL", "FAIL"]
    # each visit's part at fault (#67): the worn valve's friction the same along the stroke, said as such
    assert re.findall(r'<td class="part">([^<]*)</td>', story) == ["none", "none", "none", "valve or rack"]
    assert 'alt="wear trend of V-0815"' in story and "data:image/svg+xml;base64," in story
    withdrawn = client.get("/valve", params={"id": "V-0815-typo"}).text
    assert "WITHDRAWN" in withdrawn and "valve id typed wrong" in withdrawn
    changed = client.get("/valve", params={"id": "V-4711"}).text
    assert "CHANGED: indexed again with other content" in changed
    assert re.findall(r'<td class="verdict (\w+)">', changed) == ["FAIL"]  # the first indexing stands, not the PASS


def test_the_rigs_page_says_service_due_from_the_drift_and_shows_skips(client: TestClient) -> None:
    signed_in(client)
    page = client.get("/rigs").text
    sections = dict(re.findall(r'<section class="rig" data-station="([^"]+)">(.*?)</section>', page, re.S))
    assert "Service due by" in sections["Werkstatt Nord 1"] and "af trend reaches its limit" in sections[
        "Werkstatt Nord 1"]
    assert "Service due now" in sections["Werkstatt Süd 2"] and "LVDT zero" in sections["Werkstatt Süd 2"]
    assert "1 skipped when due" in sections["Werkstatt Ost 3"]
    assert "No trend heading for a limit" in sections["Werkstatt West 4"]
    assert sections["Werkstatt Nord 1"].count('<td class="verdict GO">GO</td>') == 4


@pytest.fixture(scope="module")
def real_records(tmp_path_factory: pytest.TempPathFactory) -> list[Path]:
    """Three simulated tests' record folders, as the bench writes them (copied by the tests that change them)."""
    from edc_bench.bench import run_simulated_test
    from edc_bench.config import load_variant
    from edc_bench.records.record import write_record

    out = tmp_path_factory.mktemp("real")
    return [write_record(run_simulated_test(load_variant(), "faulty", seed, valve_id=f"V-R{seed}"), out,
                         figure=False) for seed in (3, 4, 5)]


def test_a_report_is_drawn_only_from_a_record_the_history_indexed_inside_the_records_folder(
        demo_db: Path, records_dir: Path, real_records: list[Path], tmp_path: Path) -> None:
    import shutil

    from edc_bench.records.reader import load_record
    from edc_bench.web.app import WebConfig, create_app
    from edc_bench.web.sessions import Sessions

    db = tmp_path / "own.sqlite"
    shutil.copy(demo_db, db)
    folders = {name: Path(shutil.copytree(real, records_dir / real.name))
               for name, real in zip(("kept", "record-edited", "trace-edited"), real_records, strict=True)}
    outside = shutil.copytree(real_records[0], tmp_path / "outside" / "a-record-elsewhere")
    (folders["kept"] / "report.pdf").write_bytes(b"%PDF-1.4 a report put in the folder by hand")
    ids = {}
    with HistoryStore(f"sqlite:///{db}") as store:
        for name, folder in folders.items():
            store.add(load_record(folder), folder)
            ids[name] = store.list(Filters(valve_id=load_record(folder).valve_id))[0].id
        for name, folder in (("outside", str(outside)), ("climbing", str(records_dir / ".." / "outside")),
                             ("etc", "/etc"), ("no-digest", str(folders["kept"]))):
            store.add_row({"record_dir": folder, "started_at": "2026-11-20T08:00:00+00:00", "valve_id": f"R-{name}",
                           "pump_serial": "P", "variant": "p-edc-default", "part_number": "PE", "verdict": "PASS",
                           "station": "s", "operator": "o", "clock": "real-time", "software_version": "t",
                           "reason": "", "test_key": f"report-{name}"})
            ids[name] = store.list(Filters(valve_id=f"R-{name}"))[0].id
    # after indexing: a verdict edited in one record.json, the trace replaced in another (record.json untouched)
    edited = folders["record-edited"] / "record.json"
    edited.write_text(edited.read_text().replace('"verdict": "FAIL"', '"verdict": "PASS"', 1))
    doc = json.loads((folders["trace-edited"] / "record.json").read_text())
    trace = next(name for name in doc["integrity"]["files"] if "trace" in name)
    (folders["trace-edited"] / trace).write_bytes((folders["trace-edited"] / trace).read_bytes() + b"\0")
    app = create_app(WebConfig(url=f"sqlite:///{db}", records_dir=records_dir, token=TOKEN), Sessions())
    with TestClient(app, base_url="https://testserver", follow_redirects=False) as own:
        signed_in(own)
        good = own.get(f"/report/{ids['kept']}")
        assert good.status_code == 200 and good.headers["content-type"] == "application/pdf"
        assert good.content.startswith(b"%PDF") and b"put in the folder by hand" not in good.content  # drawn anew
        assert own.get(f"/report/{ids['kept']}").content == good.content  # kept, not drawn again
        refused = own.get(f"/report/{ids['record-edited']}")
        assert refused.status_code == 409 and "not the one the history indexed" in refused.text
        refused = own.get(f"/report/{ids['trace-edited']}")
        assert refused.status_code == 409 and "changed after its test wrote it" in refused.text, refused.text
        assert trace in refused.text and "edc-bench-report-" not in refused.text  # no folder of the server's
        refused = own.get(f"/report/{ids['no-digest']}")
        assert refused.status_code == 409 and "kept no digest" in refused.text
        for name in ("outside", "climbing", "etc"):
            refused = own.get(f"/report/{ids[name]}")
            assert refused.status_code == 403 and not refused.content.startswith(b"%PDF"), name
            assert "not in the records folder" in refused.text
        assert own.get("/report/999999").status_code == 400
        assert own.get("/report/..%2f..%2fetc%2fpasswd").status_code == 404


def test_a_report_is_drawn_from_checked_copies_whatever_lies_beside_or_changes_meanwhile(
        real_records: list[Path], tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The review of #55: drawing read a MARGINAL's retest from any folder beside the record (no digest), and read
    the record's files while drawing (a record swapped in and back between the two checks was drawn)."""
    import hashlib
    import shutil

    from edc_bench.records import report
    from edc_bench.web.reports import IndexedRecord, ReportBusy, ReportDrawer

    records = tmp_path / "records"
    test, retest, stranger = (Path(shutil.copytree(r, records / r.name)) for r in real_records)
    digest = {f: hashlib.sha256((f / "record.json").read_bytes()).hexdigest() for f in (test, retest, stranger)}
    seen: dict[str, object] = {}
    real_draw = report.draw_report

    def drawing(folder: Path, out_dir: Path, note: str, pngs: bool = True) -> tuple[Path, tuple[Path, ...]]:
        # meanwhile, someone replaces the record in the records folder by another genuine one
        (test / "record.json").write_bytes((stranger / "record.json").read_bytes())
        seen["folder"], seen["beside"] = folder, sorted(p.name for p in folder.parent.iterdir())
        seen["drawn"] = hashlib.sha256((folder / "record.json").read_bytes()).hexdigest()
        return real_draw(folder, out_dir, note, pngs)

    monkeypatch.setattr(report, "draw_report", drawing)
    drawer = ReportDrawer()
    pdf = drawer.pdf(IndexedRecord(test, digest[test]), "history test 1",
                     IndexedRecord(retest, "0" * 64))  # a retest whose record is not the one indexed
    assert pdf.startswith(b"%PDF")
    assert seen["folder"] != test and seen["drawn"] == digest[test]  # the checked copy, not the swapped file
    assert seen["beside"] == [test.name]  # neither the stranger beside it nor a retest not as indexed
    (test / "record.json").write_bytes((stranger / "record.json").read_bytes())
    drawer2 = ReportDrawer()
    drawer2.pdf(IndexedRecord(stranger, digest[stranger]), "history test 3", IndexedRecord(retest, digest[retest]))
    assert seen["beside"] == sorted([stranger.name, retest.name])  # the retest the history holds, as indexed
    with drawer2._one_at_a_time:  # another report being drawn: this one is asked again later, not queued
        with pytest.raises(ReportBusy):
            drawer2.pdf(IndexedRecord(retest, digest[retest]), "history test 2")


def test_a_withdrawn_tests_report_is_not_drawn(demo_db: Path, records_dir: Path, real_records: list[Path],
                                               tmp_path: Path) -> None:
    import shutil

    from edc_bench.records.reader import load_record
    from edc_bench.web.app import WebConfig, create_app
    from edc_bench.web.sessions import Sessions

    db = tmp_path / "own.sqlite"
    shutil.copy(demo_db, db)
    folder = Path(shutil.copytree(real_records[0], records_dir / real_records[0].name))
    with HistoryStore(f"sqlite:///{db}") as store:
        store.add(load_record(folder), folder)
        test_id = store.list(Filters(valve_id=load_record(folder).valve_id))[0].id
        store.withdraw_test(test_id, "mounted the wrong valve")
    app = create_app(WebConfig(url=f"sqlite:///{db}", records_dir=records_dir, token=TOKEN), Sessions())
    with TestClient(app, base_url="https://testserver", follow_redirects=False) as own:
        signed_in(own)
        refused = own.get(f"/report/{test_id}")
        assert refused.status_code == 409 and "not the test as it stands" in refused.text


def test_the_models_page_shows_what_each_adoption_was_decided_on(client: TestClient) -> None:
    import csv
    import io

    signed_in(client)
    page = client.get("/models").text
    current = page[page.index('<table id="current">'):page.index("</table>")]
    # the demo's first adoption: a shop candidate's cross-validated figures beside the shipped model it replaced
    assert "<strong>93.0 %</strong> right on 120 labelled tests (40 worn or faulty; 5-fold cross-validation)" in current
    assert "The model it replaced, p-edc-default: 81.0 %, 13 worn passed" in current
    rows = list(csv.DictReader(io.StringIO(client.get("/models.csv").text)))
    assert {(r["model_name"], r["cv_accuracy"], r["labels"], r["replaced_model"], r["replaced_worn_passed"])
            for r in rows} == {("shop-2026-10", "0.93", "120", "p-edc-default", "13"),
                               ("shop-2026-11", "0.93", "160", "p-edc-default", "17")}


def test_an_adoption_whose_evaluation_is_no_evaluation_leaves_the_models_page_working(demo_db: Path,
                                                                                      tmp_path: Path) -> None:
    """The review of #55: an engineer's login may write any text as an adoption's evaluation, and adoptions stay;
    a figure json reads as infinity made the models page fail for good."""
    import shutil

    from edc_bench.learning.candidate_evaluation import CandidateEvaluation, Score
    from edc_bench.web.app import WebConfig, create_app
    from edc_bench.web.sessions import Sessions

    db = tmp_path / "own.sqlite"
    shutil.copy(demo_db, db)
    shown = CandidateEvaluation(5, 40, 12, Score("<script>alert(1)</script>", 40, 0.9, 1, 0.9, 1, 1),
                                Score('"><img src=x onerror=alert(1)>', 40, 0.5, 1, 0.5, 9, 1, True), "b" * 64)
    with HistoryStore(f"sqlite:///{db}") as store:
        for n, text in enumerate(('{"folds": 1e999}', "[" * 50_000, shown.to_json())):
            store.add_adoption(f"odd-{n}", f"{n}" * 64, "Werkstatt Ost 3", "ines", evaluation=text)
    app = create_app(WebConfig(url=f"sqlite:///{db}", token=TOKEN), Sessions())
    with TestClient(app, base_url="https://testserver", follow_redirects=False) as own:
        signed_in(own)
        page = own.get("/models")
        assert page.status_code == 200 and own.get("/models.csv").status_code == 200
        assert page.text.count("no evaluation recorded") >= 2
        assert "<script>alert" not in page.text and "&lt;script&gt;alert(1)&lt;/script&gt;" not in page.text
        assert "&lt;img src=x onerror=alert(1)&gt;" in page.text and "<img src=x" not in page.text
        assert "it had learnt from these labels" in page.text


def test_every_table_exports_csv_and_a_formula_stays_text(client: TestClient) -> None:
    signed_in(client)
    for path in ("/chain/verdicts.csv", "/chain/invalid.csv", "/chain/days.csv", "/chain/stations.csv", "/rigs.csv",
                 "/models.csv", "/valve.csv?id=V-0815"):
        response = client.get(path)
        assert response.status_code == 200 and response.headers["content-type"].startswith("text/csv"), path
        assert len(response.text.splitlines()) >= 2, path
    odd = client.get("/valve.csv", params={"id": ODD_VALVE_IDS[1]}).text
    assert "V-1'; DROP TABLE tests;--" in odd
    assert client.get("/chain/nothing.csv").status_code == 400


def test_every_time_shown_is_local_with_its_offset(client: TestClient) -> None:
    signed_in(client)
    page = client.get("/valve", params={"id": "V-0815"}).text
    times = re.findall(r"<td>(\d{4}-\d\d-\d\d \d\d:\d\d [+-]\d\d:\d\d)</td>", page)
    assert len(times) >= 8


def _copy_with(demo_db: Path, tmp_path: Path, started_at: str) -> Path:
    import shutil

    db = tmp_path / "copy.sqlite"
    shutil.copy(demo_db, db)
    with HistoryStore(f"sqlite:///{db}") as store:
        store.add_row({"record_dir": "/old", "started_at": started_at, "valve_id": "V-OLD", "pump_serial": "P",
                       "variant": "p-edc-default", "part_number": "PE", "verdict": "FAIL",
                       "station": "Werkstatt Nord 1",
                       "operator": "o", "clock": "real-time", "software_version": "t", "reason": "", "test_key": "old"})
    return db


def test_the_chain_page_shows_the_last_30_days_unless_the_days_are_cleared(demo_db: Path, tmp_path: Path) -> None:
    import datetime as dt

    from edc_bench.web.app import WebConfig, create_app
    from edc_bench.web.sessions import Sessions

    old = (dt.datetime.now(dt.UTC) - dt.timedelta(days=45)).isoformat(timespec="seconds")
    db = _copy_with(demo_db, tmp_path, old)
    with TestClient(create_app(WebConfig(url=f"sqlite:///{db}", token=TOKEN), Sessions()),
                    base_url="https://testserver", follow_redirects=False) as client:
        signed_in(client)
        recent = client.get("/chain").text
        everything = client.get("/chain", params={"since": ""}).text
    assert int(_figure(everything, "tests")) == int(_figure(recent, "tests")) + 1
    first_day = (dt.date.today() - dt.timedelta(days=30)).isoformat()
    assert f'name="since" value="{first_day}"' in recent and "The last 30 days" in recent


def test_a_chain_of_many_rigs_is_a_table_each_rig_charted_on_its_own_page(tmp_path: Path) -> None:
    from edc_bench.history.demo_chain import fill_demo_chain
    from edc_bench.web.app import CHARTS_AT_ONCE, WebConfig, create_app
    from edc_bench.web.sessions import Sessions

    db = tmp_path / "many.sqlite"
    with HistoryStore(f"sqlite:///{db}") as store:
        fill_demo_chain(store, stations=CHARTS_AT_ONCE + 2, days=21, tests_per_day=1)
    with TestClient(create_app(WebConfig(url=f"sqlite:///{db}", token=TOKEN), Sessions()),
                    base_url="https://testserver", follow_redirects=False) as client:
        signed_in(client)
        page = client.get("/rigs").text
        assert len(re.findall(r'<tr data-station="', page)) == CHARTS_AT_ONCE + 2 and "<img" not in page
        assert "due now (LVDT zero)" in page
        one = client.get("/rigs", params={"station": "Werkstatt Süd 2"}).text
        assert one.count("<img") == 1 and "Service due now" in one


def test_an_abandoned_session_is_closed_when_it_expires(demo_db: Path) -> None:
    from edc_bench.web.sessions import Sessions
    from web_site import FakeClock

    class Store:
        closed = False

        def close(self) -> None:
            self.closed = True

    clock = FakeClock()
    sessions = Sessions(idle_s=60, max_s=3600, clock=clock)
    abandoned = Store()
    sessions.start("ana", abandoned)  # type: ignore[arg-type]
    clock.now_s += 61
    sessions.start("jonas", Store())  # type: ignore[arg-type]  # any sign-in sweeps the expired ones
    assert abandoned.closed and len(sessions) == 1


def test_failed_access_tokens_are_throttled(client: TestClient) -> None:
    for _ in range(5):
        form = client.get("/signin")
        csrf = re.search(r'name="csrf" value="([^"]+)"', form.text).group(1)  # type: ignore[union-attr]
        assert "wrong access token" in client.post("/signin", data={"csrf": csrf, "password": "guess"}).text
    form = client.get("/signin")
    csrf = re.search(r'name="csrf" value="([^"]+)"', form.text).group(1)  # type: ignore[union-attr]
    assert "too many failed sign-ins" in client.post("/signin", data={"csrf": csrf, "password": TOKEN}).text


def test_the_demo_chain_never_goes_into_a_history_that_holds_tests(demo_db: Path, tmp_path: Path) -> None:
    import shutil

    from edc_bench.history.demo_chain import fill_demo_chain

    db = tmp_path / "station.sqlite"
    shutil.copy(demo_db, db)
    with HistoryStore(f"sqlite:///{db}") as store, pytest.raises(ValueError, match="holds tests already"):
        fill_demo_chain(store)


def test_a_history_of_more_stations_than_sqlite_joins_in_one_select_is_summed(tmp_path: Path) -> None:
    """SQLite joins at most 500 SELECTs in one compound: the stations' latest tests are asked in parts."""
    with HistoryStore(f"sqlite:///{tmp_path / 'many.sqlite'}") as store:
        for k in range(650):
            store.map_login(f"login{k}", f"Station {k:03d}", None, "admin")
        store.add_row({"record_dir": "/r/1", "started_at": "2026-11-20T08:00:00+00:00", "valve_id": "V-1",
                       "pump_serial": "P", "variant": "p-edc-default", "part_number": "PE", "verdict": "PASS",
                       "station": "Station 649", "operator": "o", "clock": "real-time", "software_version": "t",
                       "reason": "", "test_key": "many-1"})
        import datetime as dt

        summary = chain_summary(store, Filters(), now=dt.datetime(2026, 11, 21, tzinfo=dt.UTC))
    assert len(summary.stations) == 650 and summary.tests == 1
    assert [s.station for s in summary.stations if not s.quiet] == ["Station 649"]


def test_a_record_is_found_by_its_folders_name_in_the_records_folder(records_dir: Path) -> None:
    from edc_bench.web.reports import record_folder

    (records_dir / "20261120T080000+0000-V-1").mkdir()
    (records_dir / "20261120T080000+0000-V-1" / "record.json").write_text("{}")
    station_path = "/home/bench3/records/20261120T080000+0000-V-1"  # where the station indexed it
    assert record_folder(records_dir, station_path) == (records_dir / "20261120T080000+0000-V-1").resolve()
    assert record_folder(records_dir, "/etc/..") is None and record_folder(records_dir, "..") is None
    (records_dir / "linked").mkdir()
    (records_dir / "linked" / "record.json").symlink_to("/etc/hostname")  # a link out of the records
    assert record_folder(records_dir, str(records_dir / "linked")) is None
