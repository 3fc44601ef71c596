"""The web view in a real browser (Debian's Chromium driven by Selenium, as .ci/run installs them; skipped, saying
why, where they are missing): sign in through the form, read each page as a person does, open a valve's PDF
report, and take each page's screenshot (docs/web.md shows them: set EDC_BENCH_WEB_SCREENSHOTS=docs/images/web to
write them there)."""

from __future__ import annotations

import contextlib
import os
import shutil
import socket
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from urllib.parse import quote

import httpx2 as httpx
import pytest
from web_site import NOW, TOKEN

from edc_bench.bench import run_simulated_test
from edc_bench.config import load_variant
from edc_bench.history.demo_chain import ODD_VALVE_IDS, fill_demo_chain
from edc_bench.history.store import Filters, HistoryStore
from edc_bench.history.summary import chain_summary
from edc_bench.records.reader import load_record
from edc_bench.records.record import write_record
from edc_bench.records.report import draw_report
from edc_bench.web.app import WebConfig, create_app

CHROMIUM, CHROMEDRIVER = shutil.which("chromium") or "/usr/bin/chromium", shutil.which("chromedriver") or \
    "/usr/bin/chromedriver"
WAIT_S = 30.0
#: a PDF report is drawn on request (2-3 s quiet, matplotlib): httpx's default 5 s was twice that, and failed beside
#: a CPU load; a hang guard is many times what it needs
PDF_WAIT_S = 120.0

pytestmark = pytest.mark.skipif(not (Path(CHROMIUM).exists() and Path(CHROMEDRIVER).exists()),
                                reason="Chromium and its driver are not installed here (Debian: apt-get install "
                                       "chromium chromium-driver; .ci/run installs them)")


@contextlib.contextmanager
def _served(config: WebConfig) -> Iterator[str]:
    """The application for ``config`` served by uvicorn on a free port, as ``edc-bench web`` serves it; yields its
    URL."""
    import uvicorn

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    server = uvicorn.Server(uvicorn.Config(create_app(config), host="127.0.0.1", port=port, log_level="warning"))
    thread = threading.Thread(target=server.run, daemon=True)
    thread.start()
    deadline = time.monotonic() + WAIT_S
    while not server.started and time.monotonic() < deadline:
        time.sleep(0.05)
    assert server.started, "the server did not start"
    try:
        yield f"http://127.0.0.1:{port}"
    finally:
        server.should_exit = True
        thread.join(WAIT_S)


@pytest.fixture(scope="module")
def site(tmp_path_factory: pytest.TempPathFactory) -> Iterator[dict[str, object]]:
    """The demo chain and one real test's record folder (its report drawn), served by uvicorn on a free port."""

    base = tmp_path_factory.mktemp("site")
    records = base / "records"
    folder = write_record(run_simulated_test(load_variant(), "faulty", 3), records, figure=False)
    draw_report(folder)
    db = base / "history.sqlite"
    with HistoryStore(f"sqlite:///{db}") as store:
        fill_demo_chain(store, now=NOW)
        store.add(load_record(folder), folder)
        real = store.list(Filters(simulated=True))[-1]
    with _served(WebConfig(url=f"sqlite:///{db}", records_dir=records, token=TOKEN)) as url:
        yield {"url": url, "db": db, "real": real}


@pytest.fixture(scope="module")
def browser(tmp_path_factory: pytest.TempPathFactory) -> Iterator[object]:
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    options = webdriver.ChromeOptions()
    options.binary_location = CHROMIUM
    for flag in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                 "--disable-background-networking", "--disable-component-update", "--disable-sync",
                 "--disable-dev-shm-usage", "--window-size=1280,1000",
                 f"--user-data-dir={tmp_path_factory.mktemp('chromium')}"):
        options.add_argument(flag)
    driver = webdriver.Chrome(service=Service(CHROMEDRIVER), options=options)
    driver.implicitly_wait(0)
    yield driver
    driver.quit()


def _screenshots() -> Path | None:
    folder = os.environ.get("EDC_BENCH_WEB_SCREENSHOTS")
    return Path(folder) if folder else None


def _shot(driver: object, name: str) -> None:
    folder = _screenshots()
    if folder is not None:
        folder.mkdir(parents=True, exist_ok=True)
        height = driver.execute_script(  # type: ignore[attr-defined]
            "return Math.max(document.body.scrollHeight, document.documentElement.scrollHeight, "
            "document.querySelector('main').getBoundingClientRect().bottom + window.scrollY)")
        driver.set_window_size(1280, min(max(int(height) + 160, 600), 2600))  # type: ignore[attr-defined]
        driver.save_screenshot(str(folder / f"{name}.png"))  # type: ignore[attr-defined]
        driver.set_window_size(1280, 1000)  # type: ignore[attr-defined]


def _wait_for(driver: object, css: str) -> object:
    from selenium.webdriver.common.by import By
    from selenium.webdriver.support import expected_conditions
    from selenium.webdriver.support.ui import WebDriverWait

    return WebDriverWait(driver, WAIT_S).until(expected_conditions.presence_of_element_located((By.CSS_SELECTOR, css)))


def _images_drawn(driver: object) -> bool:
    return bool(driver.execute_script(  # type: ignore[attr-defined]
        "return [...document.images].length > 0 && [...document.images].every(i => i.complete && i.naturalWidth > 0)"))


def _sign_in(driver: object, url: str) -> None:
    from selenium.webdriver.common.by import By

    driver.get(url + "/valves?q=V-08")  # type: ignore[attr-defined]
    _wait_for(driver, "form.signin")
    _shot(driver, "signin")
    driver.find_element(By.NAME, "login").send_keys("ana")  # type: ignore[attr-defined]
    driver.find_element(By.NAME, "password").send_keys(TOKEN)  # type: ignore[attr-defined]
    driver.find_element(By.ID, "signin").click()  # type: ignore[attr-defined]
    _wait_for(driver, "#found")


def test_a_person_signs_in_and_reads_every_page(site: dict, browser: object) -> None:
    from selenium.common.exceptions import NoAlertPresentException
    from selenium.webdriver.common.by import By

    driver, url = browser, str(site["url"])
    _sign_in(driver, url)  # and lands on the page asked for before signing in
    assert driver.current_url.endswith("/valves?q=V-08")  # type: ignore[attr-defined]
    # the chain: its figures as the history computes them
    driver.get(url + "/chain")  # type: ignore[attr-defined]
    _wait_for(driver, "#tests")
    with HistoryStore(f"sqlite:///{site['db']}", must_exist=True) as store:
        summary = chain_summary(store, Filters(simulated=False))
    assert driver.find_element(By.ID, "tests").text == str(summary.tests)  # type: ignore[attr-defined]
    assert driver.find_element(By.ID, "first-pass").text == f"{summary.first_pass_rate * 100:.1f} %"  # type: ignore
    quiet = driver.find_elements(By.CSS_SELECTOR, "#stations tr.quiet td:first-child")  # type: ignore[attr-defined]
    assert [q.text for q in quiet] == ["Werkstatt West 4"]
    assert _images_drawn(driver)
    _shot(driver, "chain")
    # a filter typed in the form
    driver.find_element(By.NAME, "station").send_keys("Werkstatt Süd 2")  # type: ignore[attr-defined]
    driver.find_element(By.CSS_SELECTOR, "form.filters button").click()  # type: ignore[attr-defined]
    _wait_for(driver, "#stations")
    with HistoryStore(f"sqlite:///{site['db']}", must_exist=True) as store:
        one = chain_summary(store, Filters(simulated=False, station="Werkstatt Süd 2"))
    assert driver.find_element(By.ID, "tests").text == str(one.tests) != str(summary.tests)  # type: ignore
    # the rigs: the drifted one says service due, its chart drawn
    driver.get(url + "/rigs")  # type: ignore[attr-defined]
    _wait_for(driver, "section.rig")
    nord = driver.find_element(By.CSS_SELECTOR, 'section.rig[data-station="Werkstatt Nord 1"]')  # type: ignore
    assert "Service due by" in nord.text and "af trend reaches its limit" in nord.text
    assert nord.find_element(By.CSS_SELECTOR, "img.chart").get_property("naturalWidth") > 0
    sued = driver.find_element(By.CSS_SELECTOR, 'section.rig[data-station="Werkstatt Süd 2"]')  # type: ignore
    assert "Service due now" in sued.text
    _shot(driver, "rigs")
    # a valve's story: search, click, its decisions and its trend
    driver.get(url + "/valves")  # type: ignore[attr-defined]
    box = _wait_for(driver, "input[name=q]")
    box.send_keys("V-0815")  # type: ignore[attr-defined]
    driver.find_element(By.CSS_SELECTOR, "form.filters button").click()  # type: ignore[attr-defined]
    _wait_for(driver, "#found a")
    _shot(driver, "valves")
    driver.find_element(By.LINK_TEXT, "V-0815").click()  # type: ignore[attr-defined]
    _wait_for(driver, "#visits")
    decisions = [td.text for td in driver.find_elements(By.CSS_SELECTOR, "#visits td.verdict")]  # type: ignore
    assert decisions == ["PASS", "PASS", "MARGINAL", "FAIL"]
    assert _images_drawn(driver)
    _shot(driver, "valve")
    # the withdrawn test as such
    driver.get(url + "/valve?id=V-0815-typo")  # type: ignore[attr-defined]
    assert "WITHDRAWN" in _wait_for(driver, "#rows").text  # type: ignore[attr-defined]
    # an id holding a script is text: no alert, the id shown as typed
    for valve in ODD_VALVE_IDS:
        driver.get(url + "/valve?id=" + quote(valve, safe=""))  # type: ignore[attr-defined]
        shown = _wait_for(driver, "#valve-id")
        assert shown.text == valve  # type: ignore[attr-defined]
        with pytest.raises(NoAlertPresentException):
            driver.switch_to.alert.text  # type: ignore[attr-defined]  # noqa: B018
    # the models
    driver.get(url + "/models")  # type: ignore[attr-defined]
    assert "shop-2026-10" in _wait_for(driver, "#current").text  # type: ignore[attr-defined]
    _shot(driver, "models")


def test_a_valves_pdf_report_opens_from_its_page(site: dict, browser: object) -> None:
    from selenium.webdriver.common.by import By

    driver, url, real = browser, str(site["url"]), site["real"]
    driver.get(url + "/chain")  # type: ignore[attr-defined]
    if "/signin" in driver.current_url:  # type: ignore[attr-defined]
        _sign_in(driver, url)
    driver.get(url + "/valve?id=" + quote(str(real.valve_id), safe=""))  # type: ignore[attr-defined]
    link = _wait_for(driver, "#visits a")
    href = link.get_attribute("href")  # type: ignore[attr-defined]
    assert href.endswith(f"/report/{real.id}")
    # the browser's own session opens it (its cookie, as a click would send it)
    cookies = {c["name"]: c["value"] for c in driver.get_cookies()}  # type: ignore[attr-defined]
    report = httpx.get(href, cookies=cookies, timeout=PDF_WAIT_S)
    assert report.status_code == 200 and report.headers["content-type"] == "application/pdf"
    assert report.content.startswith(b"%PDF")
    driver.find_element(By.CSS_SELECTOR, "form.signout button").click()  # type: ignore[attr-defined]
    _wait_for(driver, "form.signin")
    assert httpx.get(href, cookies=cookies, timeout=PDF_WAIT_S).status_code == 303  # signed out: the cookie opens nothing


# --- the chain's PostgreSQL, each role signing in with its own database login ---------------------------------

PG_LOGINS = {"station000": "edc_station", "ines_pg": "edc_engineer"}


@pytest.fixture(scope="module")
def pg_site(tmp_path_factory: pytest.TempPathFactory, postgres_url: str) -> Iterator[dict[str, object]]:
    """The benchmark's bulk chain (5 stations, a year of tests and weekly self-checks: Station 000's rig drifts,
    Station 001's last check is NO-GO, one test per station withdrawn) on the tests' PostgreSQL with the chain's
    roles; one real test indexed by a station's login, its record in the records folder; another row of that
    station's forged by the owner with the triggers off. Served by uvicorn as a chain's server is (each person
    signs in as their own login)."""
    import sqlalchemy as sa
    from pg_server import new_database

    from edc_bench.history.bulk_chain import fill_bulk_chain
    from edc_bench.history.roles import setup_roles
    from edc_bench.history.schema import amendments, tests

    url = new_database(postgres_url)
    engine = sa.create_engine(url)
    # the roles first, on empty tables: handing a table to edc_owner right after a bulk load can deadlock with
    # PostgreSQL's autovacuum analysing it (seen once in CI: each waits for the other's lock on tests)
    with engine.begin() as conn:
        setup_roles(conn)
        for login, role in PG_LOGINS.items():
            conn.exec_driver_sql(f"DO $$ BEGIN IF NOT EXISTS (SELECT FROM pg_roles WHERE rolname = '{login}') THEN "
                                 f"CREATE ROLE {login} LOGIN; END IF; END $$")
            conn.exec_driver_sql(f"GRANT {role} TO {login}")
    fill_bulk_chain(url, 2000, stations=5)
    with engine.connect() as conn:
        withdrawn = conn.execute(sa.select(tests.c.valve_id).join(amendments, amendments.c.target_id == tests.c.id)
                                 .limit(1)).scalar_one()
    engine.dispose()
    with HistoryStore(url) as owner:
        owner.map_login("ines_pg", None, "Ines Braun", "admin")
    records = tmp_path_factory.mktemp("pg-site") / "records"
    folder = write_record(run_simulated_test(load_variant(), "faulty", 7, valve_id="V-PG-REAL"), records,
                          figure=False)
    real = load_record(folder)
    forged = "V-PG-FORGED"
    with HistoryStore(url.replace("://postgres@", "://station000@")) as station:
        assert station.add(real, folder) == "new"
        assert station.add_row({"record_dir": "/records/forged", "started_at": "2026-11-20T08:00:00+00:00",
                                "valve_id": forged, "pump_serial": "P-1", "variant": "p-edc-default",
                                "part_number": "PE", "verdict": "FAIL", "station": "ignored", "operator": "ana",
                                "clock": "real-time", "software_version": "0.1.0", "reason": "",
                                "test_key": "forged-1", "record_sha256": "f" * 64}) == "new"
    engine = sa.create_engine(url)
    with engine.begin() as conn:  # the owner's rights: the append-only trigger held off, the FAIL turned PASS
        conn.exec_driver_sql("ALTER TABLE tests DISABLE TRIGGER tests_append_only")
        conn.execute(sa.update(tests).where(tests.c.valve_id == forged).values(verdict="PASS"))
        conn.exec_driver_sql("ALTER TABLE tests ENABLE TRIGGER tests_append_only")
    engine.dispose()
    server_url = url.replace("://postgres@", "://@")
    with _served(WebConfig(url=server_url, records_dir=records)) as site_url:
        yield {"url": site_url, "db": url, "withdrawn": withdrawn, "forged": forged,
               "real_verdict": str(real.verdict)}


def _sign_in_as(driver: object, url: str, login: str, then: str) -> None:
    from selenium.webdriver.common.by import By

    driver.get(url + then)  # type: ignore[attr-defined]
    _wait_for(driver, "form.signin")
    driver.find_element(By.NAME, "login").send_keys(login)  # type: ignore[attr-defined]
    driver.find_element(By.NAME, "password").send_keys("the tests' server trusts its logins")  # type: ignore
    driver.find_element(By.ID, "signin").click()  # type: ignore[attr-defined]
    assert _wait_for(driver, "span.who").text == login  # type: ignore[attr-defined]  # signed in pages only


def _sign_out(driver: object) -> None:
    from selenium.webdriver.common.by import By

    driver.find_element(By.CSS_SELECTOR, "form.signout button").click()  # type: ignore[attr-defined]
    _wait_for(driver, "form.signin")


@pytest.mark.parametrize("login", ["station000", "ines_pg", "postgres"])
def test_each_role_reads_the_chains_postgresql_in_a_browser(pg_site: dict, browser: object, login: str) -> None:
    from selenium.webdriver.common.by import By

    driver, url = browser, str(pg_site["url"])
    _sign_in_as(driver, url, login, "/chain?since=")  # all time, the simulated rig left out
    with HistoryStore(str(pg_site["db"]).replace("://postgres@", f"://{login}@")) as store:
        summary = chain_summary(store, Filters(simulated=False))
    assert driver.find_element(By.ID, "tests").text == str(summary.tests)  # type: ignore[attr-defined]
    assert driver.find_element(By.ID, "first-pass").text == f"{summary.first_pass_rate * 100:.1f} %"  # type: ignore
    assert _images_drawn(driver)
    # the rigs: the drifted one says when service is due, the one whose last check was NO-GO says now
    driver.get(url + "/rigs?station=" + quote("Station 000"))  # type: ignore[attr-defined]
    drifted = _wait_for(driver, 'section.rig[data-station="Station 000"]')
    assert "Service due" in drifted.text and "af" in drifted.text  # type: ignore[attr-defined]
    assert _images_drawn(driver)
    driver.get(url + "/rigs?station=" + quote("Station 001"))  # type: ignore[attr-defined]
    assert "Service due now" in _wait_for(driver, 'section.rig[data-station="Station 001"]').text  # type: ignore
    # a valve's rows: the withdrawn one and the forged one shown as such
    driver.get(url + "/valve?id=" + quote(str(pg_site["withdrawn"]), safe=""))  # type: ignore[attr-defined]
    assert "WITHDRAWN" in _wait_for(driver, "#rows").text  # type: ignore[attr-defined]
    driver.get(url + "/valve?id=" + quote(str(pg_site["forged"]), safe=""))  # type: ignore[attr-defined]
    assert "ALTERED" in _wait_for(driver, "#rows").text  # type: ignore[attr-defined]
    # the real test's page: its decision, and its report opened with the browser's own session
    driver.get(url + "/valve?id=V-PG-REAL")  # type: ignore[attr-defined]
    link = _wait_for(driver, "#visits a")
    decisions = [td.text for td in driver.find_elements(By.CSS_SELECTOR, "#visits td.verdict")]  # type: ignore
    assert decisions == [pg_site["real_verdict"]]
    cookies = {c["name"]: c["value"] for c in driver.get_cookies()}  # type: ignore[attr-defined]
    report = httpx.get(link.get_attribute("href"), cookies=cookies, timeout=PDF_WAIT_S)  # type: ignore[attr-defined]
    assert report.status_code == 200 and report.content.startswith(b"%PDF")
    _sign_out(driver)
