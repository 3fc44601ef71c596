"""The web view's fixtures (a plugin of tests/conftest.py): the demo chain in a SQLite history, the application,
and signing in as a browser does."""

from __future__ import annotations

import datetime as dt
import re
from collections.abc import Iterator
from pathlib import Path

import pytest
from starlette.testclient import TestClient

from edc_bench.history.demo_chain import fill_demo_chain
from edc_bench.history.store import HistoryStore
from edc_bench.web.app import WebConfig, create_app
from edc_bench.web.sessions import Sessions

TOKEN = "web-test-token-0123456789"
#: the demo chain's 'now' (the pages judge quiet stations by the real one)
NOW = dt.datetime.now(dt.UTC).replace(minute=0, second=0, microsecond=0)


class FakeClock:
    """Monotonic seconds the test moves on."""

    def __init__(self) -> None:
        self.now_s = 1000.0

    def __call__(self) -> float:
        return self.now_s


@pytest.fixture(scope="session")
def demo_db(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A SQLite history holding the demo chain (made once; the tests only read it)."""
    path = tmp_path_factory.mktemp("web") / "history.sqlite"
    with HistoryStore(f"sqlite:///{path}") as store:
        fill_demo_chain(store, now=NOW)
    return path


@pytest.fixture
def records_dir(tmp_path: Path) -> Path:
    folder = tmp_path / "records"
    folder.mkdir()
    return folder


def signed_in(client: TestClient, login: str = "ana", password: str = TOKEN) -> TestClient:
    """Sign ``client`` in through the form, as a browser does."""
    form = client.get("/signin")
    csrf = re.search(r'name="csrf" value="([^"]+)"', form.text)
    assert csrf is not None, form.text
    response = client.post("/signin", data={"csrf": csrf.group(1), "login": login, "password": password,
                                            "next": "/chain"}, follow_redirects=False)
    assert response.status_code == 303, response.text
    return client


@pytest.fixture
def clock() -> FakeClock:
    return FakeClock()


@pytest.fixture
def client(demo_db: Path, records_dir: Path, clock: FakeClock) -> Iterator[TestClient]:
    """The application on the demo chain, over HTTPS as a browser keeps its secure cookies, not signed in."""
    config = WebConfig(url=f"sqlite:///{demo_db}", records_dir=records_dir, token=TOKEN)
    app = create_app(config, Sessions(idle_s=1800, max_s=12 * 3600, clock=clock))
    with TestClient(app, base_url="https://testserver", follow_redirects=False) as c:
        yield c
