"""The web view on a chain's PostgreSQL: each person signs in with their database login and reads as it, so the
database's roles decide what a page may show (a real server: tests/pg_server.py; skipped where there is none)."""

from __future__ import annotations

import html
import json
import re
import time
import uuid
from pathlib import Path

import psycopg
import pytest
import sqlalchemy as sa
from web_site import signed_in
from starlette.testclient import TestClient

from edc_bench.cli import main
from edc_bench.history.roles import setup_roles
from edc_bench.history.store import Filters, HistoryStore
from edc_bench.web.app import WebConfig, create_app
from edc_bench.web.sessions import Sessions


def _login(url: str, login: str) -> str:
    return url.replace("://postgres@", f"://{login}@")


def _row(valve: str, verdict: str, key: str | None = None, sha: str = "a" * 64, area: str | None = None) -> dict:
    return {"record_dir": f"/records/{valve}", "started_at": "2026-11-20T08:00:00+00:00", "valve_id": valve,
            "pump_serial": "P-1", "variant": "p-edc-default", "part_number": "PE", "verdict": verdict,
            "station": "ignored", "operator": "ana", "clock": "real-time", "software_version": "0.1.0",
            "reason": "", "test_key": key or uuid.uuid4().hex, "record_sha256": sha, "invalid_area": area}


@pytest.fixture
def chain(postgres_db: str) -> dict[str, str]:
    """Roles, two stations' logins, an engineer and a login of no role; a few tests by each station, one withdrawn
    by the engineer, one indexed again with other content. Returns the URLs by login."""
    engine = sa.create_engine(postgres_db)
    with engine.begin() as conn:
        setup_roles(conn)
        for login, role in (("bench3", "edc_station"), ("bench4", "edc_station"), ("ines", "edc_engineer"),
                            ("visitor", None)):
            conn.exec_driver_sql(f"DO $$ BEGIN IF NOT EXISTS (SELECT FROM pg_roles WHERE rolname = '{login}') THEN "
                                 f"CREATE ROLE {login} LOGIN; END IF; END $$")
            if role:
                conn.exec_driver_sql(f"GRANT {role} TO {login}")
    engine.dispose()
    with HistoryStore(postgres_db) as owner:
        owner.map_login("bench3", "Werkstatt Nord 3", None, "admin")
        owner.map_login("bench4", "Werkstatt Süd 4", None, "admin")
        owner.map_login("ines", None, "Ines Braun", "admin")
    urls = {"owner": postgres_db, **{login: _login(postgres_db, login) for login in ("bench3", "bench4", "ines")}}
    with HistoryStore(urls["bench3"]) as bench3:
        for k, verdict in enumerate(("PASS", "PASS", "FAIL", "MARGINAL", "INVALID")):
            bench3.add_row(_row(f"N-{k}", verdict, area="bus" if verdict == "INVALID" else None))
        bench3.add_row(_row("N-9", "FAIL", key="n9"))
        bench3.add_row(_row("N-9", "PASS", key="n9", sha="b" * 64))  # a PASS indexed over its FAIL: a change
    with HistoryStore(urls["bench4"]) as bench4:
        bench4.add_row(_row('S-<b>"1"</b>', "FAIL"))
        bench4.add_row(_row("S-typo", "PASS"))
    with HistoryStore(urls["ines"]) as ines:
        typo = ines.list(Filters(valve_id="S-typo"))[0].id
        ines.withdraw_test(typo, "valve id typed wrong")
    return urls


def _client(url: str) -> TestClient:
    server = sa.engine.make_url(url).set(username=None).render_as_string(hide_password=False)
    return TestClient(create_app(WebConfig(url=server), Sessions()), base_url="https://testserver",
                      follow_redirects=False)


@pytest.mark.parametrize("login", ["bench3", "ines", "postgres"])
def test_each_role_signs_in_with_its_database_login_and_sees_the_figures_history_prints(
        chain: dict[str, str], login: str, capsys: pytest.CaptureFixture[str]) -> None:
    url = chain["owner"] if login == "postgres" else chain[login]
    with _client(chain["owner"]) as client:
        signed_in(client, login, "any: the tests' server trusts its logins")
        page = client.get("/chain").text
        assert f'<span class="who">{login}</span>' in page
    assert main(["history", "--db", url, "--summary", "--json"]) == 0
    printed = json.loads(capsys.readouterr().out)
    assert re.search(r'id="tests">(\d+)<', page).group(1) == str(printed["tests"]) == "7"  # type: ignore[union-attr]
    assert f'{printed["first_pass_rate"] * 100:.1f} %' in page
    assert '<td>bus</td><td class="num">1</td>' in page
    stations = re.findall(r"<tr(?: class=\"quiet\")?><td>([^<]+)</td>", page)
    assert {"Werkstatt Nord 3", "Werkstatt Süd 4"} <= set(stations)


def test_the_chain_is_counted_by_shop_and_filtered_to_one(chain: dict[str, str],
                                                          capsys: pytest.CaptureFixture[str]) -> None:
    """The owner says each station's shop (--map-login ... --shop); a station moved to another shop counts there."""
    owner = chain["owner"]
    assert main(["history", "--db", owner, "--map-login", "bench3", "--station", "Werkstatt Nord 3", "--shop",
                 "Nord"]) == 0
    assert main(["history", "--db", owner, "--map-login", "bench4", "--station", "Werkstatt Süd 4", "--shop",
                 "Nord"]) == 0
    assert main(["history", "--db", owner, "--map-login", "bench4", "--station", "Werkstatt Süd 4", "--shop",
                 "Süd <&>"]) == 0
    capsys.readouterr()
    assert main(["history", "--db", owner, "--summary", "--shop", "Nord", "--json"]) == 0
    nord = json.loads(capsys.readouterr().out)
    assert nord["shops"] == [{"shop": "Nord", "stations": 1, "tests": 6}]
    assert [s["station"] for s in nord["stations"]] == ["Werkstatt Nord 3"] and nord["tests"] == 6
    with _client(owner) as client:
        signed_in(client, "bench4", "pw")
        page = client.get("/chain").text
        shops = re.findall(r'<tr><td>([^<]+)</td><td class="num">(\d+)</td><td class="num">(\d+)</td></tr>', page)
        assert shops == [("Nord", "1", "6"), ("Süd &lt;&amp;&gt;", "1", "1")]
        one = client.get("/chain", params={"shop": "Süd <&>"}).text
        assert re.search(r'id="tests">(\d+)<', one).group(1) == "1"  # type: ignore[union-attr]
        csv = client.get("/chain/shops.csv").text.splitlines()
        assert csv == ["shop,stations,tests", "Nord,1,6", "Süd <&>,1,1"]
        assert client.get("/chain", params={"shop": "x' OR '1'='1"}).status_code == 200


def test_a_login_of_no_role_is_refused_at_sign_in(chain: dict[str, str]) -> None:
    with _client(chain["owner"]) as client:
        form = client.get("/signin")
        csrf = re.search(r'name="csrf" value="([^"]+)"', form.text).group(1)  # type: ignore[union-attr]
        response = client.post("/signin", data={"csrf": csrf, "login": "visitor", "password": "pw"})
        assert response.status_code == 403
        assert "this login may not read the history" in response.text
        assert client.get("/chain").status_code == 303


def test_a_login_the_server_does_not_know_is_refused(chain: dict[str, str]) -> None:
    with _client(chain["owner"]) as client:
        form = client.get("/signin")
        csrf = re.search(r'name="csrf" value="([^"]+)"', form.text).group(1)  # type: ignore[union-attr]
        response = client.post("/signin", data={"csrf": csrf, "login": "x'; DROP ROLE bench3; --", "password": "pw"})
        assert response.status_code == 403 and "sign-in refused" in response.text
    engine = sa.create_engine(chain["owner"])
    with engine.connect() as conn:
        assert conn.execute(sa.text("SELECT 1 FROM pg_roles WHERE rolname = 'bench3'")).first() is not None
    engine.dispose()


def test_a_station_sees_the_withdrawn_and_the_changed_rows_as_such(chain: dict[str, str]) -> None:
    with _client(chain["owner"]) as client:
        signed_in(client, "bench4", "pw")
        withdrawn = client.get("/valve", params={"id": "S-typo"}).text
        assert "WITHDRAWN" in withdrawn and "valve id typed wrong" in withdrawn
        changed = client.get("/valve", params={"id": "N-9"}).text
        assert "CHANGED: indexed again with other content" in changed
        assert re.findall(r'<td class="verdict (\w+)">', changed) == ["FAIL"]
        odd = client.get("/valve", params={"id": 'S-<b>"1"</b>'}).text
        assert "S-&lt;b&gt;&#34;1&#34;&lt;/b&gt;" in odd and "<b>" not in odd


def test_a_forged_row_is_shown_as_altered_and_the_rows_beside_it_stay_trusted(chain: dict[str, str]) -> None:
    """What the owner's or a superuser's rights could still do: a FAIL turned PASS with the triggers off, and a
    PASS put into the chain by hand (its hashes copied from the row before). The valve's page says so."""
    with psycopg.connect(chain["owner"].replace("postgresql+psycopg://", "postgresql://")) as conn:
        conn.execute("ALTER TABLE tests DISABLE TRIGGER tests_append_only")
        conn.execute("UPDATE tests SET verdict = 'PASS' WHERE valve_id = 'N-2'")
        conn.execute("ALTER TABLE tests ENABLE TRIGGER tests_append_only")
        conn.execute("SET session_replication_role = replica")  # no stamp: the row says what the forger typed
        conn.execute("INSERT INTO tests (id, record_dir, started_at, valve_id, pump_serial, variant, part_number, "
                     "verdict, station, operator, clock, software_version, reason, test_key, first_indexing, "
                     "prev_hash, row_hash) SELECT 9000, record_dir || '-x', started_at, 'N-2', pump_serial, variant, "
                     "part_number, 'PASS', station, operator, clock, software_version, reason, 'forged', true, "
                     "prev_hash, row_hash FROM tests WHERE valve_id = 'N-1'")
    with _client(chain["owner"]) as client:
        signed_in(client, "bench4", "pw")
        page = client.get("/valve", params={"id": "N-2"}).text
        assert page.count("ALTERED: not as the history") == 2, page
        kept = client.get("/valve", params={"id": "N-1"}).text
        assert "ALTERED" not in kept


def test_a_role_that_may_not_read_a_table_gets_a_message_not_a_traceback(chain: dict[str, str]) -> None:
    engine = sa.create_engine(chain["owner"])
    with engine.begin() as conn:  # the owner keeps the self-checks from stations (a chain may)
        conn.exec_driver_sql("REVOKE SELECT ON rig_checks FROM edc_station")
    engine.dispose()
    with _client(chain["owner"]) as client:
        signed_in(client, "bench3", "pw")
        response = client.get("/rigs")
        assert response.status_code == 403
        assert "may not" in response.text and "Traceback" not in response.text
        assert client.get("/chain").status_code in (200, 403)


def test_a_login_without_a_password_is_refused_whatever_the_server_would_take(chain: dict[str, str],
                                                                              monkeypatch: pytest.MonkeyPatch) -> None:
    """The review of #55: with no password typed, the driver took the server's own (PGPASSWORD, ~/.pgpass, which a
    station's account has for its login): anyone typing that login was signed in as it. The tests' server trusts
    every login, so an empty password would have been let in here."""
    monkeypatch.setenv("PGPASSWORD", "the station's own")
    with _client(chain["owner"]) as client:
        form = client.get("/signin")
        csrf = re.search(r'name="csrf" value="([^"]+)"', form.text).group(1)  # type: ignore[union-attr]
        response = client.post("/signin", data={"csrf": csrf, "login": "bench3", "password": ""})
        assert response.status_code == 403 and "give your database login and its password" in response.text
        assert client.get("/chain").status_code == 303


def _sign_in_form(client: TestClient, login: str, password: str) -> object:
    form = client.get("/signin")
    csrf = re.search(r'name="csrf" value="([^"]+)"', form.text).group(1)  # type: ignore[union-attr]
    return client.post("/signin", data={"csrf": csrf, "login": login, "password": password})


def test_a_login_whose_server_checks_passwords_signs_in_with_its_own_password_only(
        chain: dict[str, str], monkeypatch: pytest.MonkeyPatch) -> None:
    """The tests' server trusts its logins; a shop's asks for passwords (docs/shop-network.md). Here one login is
    made to need its password (scram-sha-256, as PostgreSQL 14 and later store them) and signs in through the
    page: a wrong password is refused, also with the right one in the environment the driver would read."""
    login, password = f"pw_{uuid.uuid4().hex[:8]}", "right horse battery staple"
    engine = sa.create_engine(chain["owner"], isolation_level="AUTOCOMMIT")
    with engine.connect() as conn:
        hba = Path(str(conn.exec_driver_sql("SHOW hba_file").scalar()))
        conn.exec_driver_sql(f"CREATE ROLE {login} LOGIN PASSWORD '{password}'")
        conn.exec_driver_sql(f"GRANT edc_station TO {login}")
        trusted = hba.read_text()
        hba.write_text(f"host all {login} 127.0.0.1/32 scram-sha-256\n{trusted}")
        conn.exec_driver_sql("SELECT pg_reload_conf()")
    direct = sa.engine.make_url(_login(chain["owner"], login))
    try:
        for _ in range(200):  # the server reads its rules again a moment after it is told to
            try:
                psycopg.connect(host=direct.host, port=direct.port, dbname=direct.database, user=login,
                                password="wrong").close()
            except psycopg.OperationalError as exc:
                assert "password authentication failed" in str(exc)
                break
            time.sleep(0.05)
        else:
            pytest.fail("the server kept trusting the login")
        monkeypatch.setenv("PGPASSWORD", password)  # what a station's account may have: never taken for the form's
        with _client(chain["owner"]) as client:
            for wrong in ("wrong", password.upper(), password + " "):
                response = _sign_in_form(client, login, wrong)
                assert response.status_code == 403 and "sign-in refused" in response.text  # type: ignore[attr-defined]
                assert client.get("/chain").status_code == 303
            assert _sign_in_form(client, login, password).status_code == 303  # type: ignore[attr-defined]
            page = client.get("/chain")
            assert page.status_code == 200 and f'<span class="who">{login}</span>' in page.text
    finally:
        hba.write_text(trusted)
        with engine.connect() as conn:
            conn.exec_driver_sql("SELECT pg_reload_conf()")
        engine.dispose()


def test_a_history_at_another_revision_says_so_at_sign_in(new_postgres_database: object) -> None:
    """The login is accepted but the history is an older edc-bench's: the page says which revision and who
    upgrades, not that the login was refused."""
    from alembic import command

    from edc_bench.history import migrate

    url = new_postgres_database(upgrade=False)  # type: ignore[operator]
    engine = sa.create_engine(url)
    with engine.begin() as conn:
        command.upgrade(migrate._config(conn), "0008")
    engine.dispose()
    with _client(url) as client:
        response = _sign_in_form(client, "postgres", "any: the tests' server trusts its logins")
        assert response.status_code == 403  # type: ignore[attr-defined]
        text = html.unescape(response.text)  # type: ignore[attr-defined]
        assert "signed in, but this history cannot be read here" in text and "sign-in refused" not in text
        assert f"is at schema revision 0008; this edc-bench needs {migrate.HEAD}" in text
        assert "edc-bench history --upgrade" in text


def test_failed_sign_ins_of_a_login_are_throttled(chain: dict[str, str]) -> None:
    with _client(chain["owner"]) as client:
        for attempt in range(6):
            form = client.get("/signin")
            csrf = re.search(r'name="csrf" value="([^"]+)"', form.text).group(1)  # type: ignore[union-attr]
            response = client.post("/signin", data={"csrf": csrf, "login": "visitor", "password": f"guess{attempt}"})
            assert response.status_code == 403
        assert "too many failed sign-ins" in response.text
        signed_in(client, "bench3", "pw")  # another login is not held back
