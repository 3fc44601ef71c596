"""The web application: routes, sign-in, CSRF, security headers (:func:`create_app`)."""

from __future__ import annotations

import contextlib
import csv
import datetime as dt
import gc
import io
import secrets
import threading
from collections.abc import AsyncIterator, Callable, Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from urllib.parse import quote

import jinja2
import sqlalchemy as sa
from starlette.applications import Starlette
from starlette.middleware import Middleware
from starlette.middleware.base import BaseHTTPMiddleware, RequestResponseEndpoint
from starlette.requests import Request
from starlette.responses import RedirectResponse, Response
from starlette.routing import Mount, Route
from starlette.staticfiles import StaticFiles
from starlette.templating import Jinja2Templates

from edc_bench.errors import EdcBenchError
from edc_bench.history.migrate import RevisionMismatch
from edc_bench.history.store import Filters, HistoryStore, parse_day
from edc_bench.history.summary import chain_summary
from edc_bench.history.visits import visits
from edc_bench.timefmt import local_text, utc_bound
from edc_bench.web import charts, views
from edc_bench.web.reports import IndexedRecord, ReportBusy, ReportDrawer, ReportRefused, record_folder
from edc_bench.web.sessions import Session, Sessions, SignInThrottle

HERE = Path(__file__).parent
SESSION_COOKIE = "edc_session"
SIGNIN_COOKIE = "edc_signin"
#: the most rigs whose charts one page draws (more: a table, each rig's chart on its own page)
CHARTS_AT_ONCE = 8
#: the chain page's days when none are asked for
DEFAULT_DAYS = 30
#: the longest text a filter or search field takes (ids and names are at most 200 characters in the history)
MAX_FIELD_CHARS = 200

#: every response's content security policy: this host's styles, images from it or data: URLs (the charts), no
#: script at all, forms only to this host, never framed
CSP = ("default-src 'none'; style-src 'self'; img-src 'self' data:; form-action 'self'; frame-ancestors 'none'; "
       "base-uri 'none'")


@dataclass(frozen=True)
class WebConfig:
    """How the application is served.

    Attributes
    ----------
    url : str
        The history: ``sqlite:///…`` (a station's) or ``postgresql+psycopg://host/db`` (the chain's; its user and
        password, if any, are replaced by the person's who signs in).
    records_dir : Path or None
        The folder the records are in: a report is served only from inside it (None: no reports served).
    token : str
        SQLite: the access token a person signs in with (printed at start).
    secure_cookies : bool
        Mark cookies Secure (browsers keep them over HTTPS, and over HTTP on 127.0.0.1/localhost only).
    idle_minutes, max_hours : float
        A session ends after this long without a request, or this long after sign-in.
    """

    url: str
    records_dir: Path | None = None
    token: str = ""
    secure_cookies: bool = True
    idle_minutes: float = 30.0
    max_hours: float = 12.0

    @property
    def is_sqlite(self) -> bool:
        """The history is a station's SQLite file."""
        return sa.engine.make_url(self.url).get_backend_name() == "sqlite"


class _SecurityHeaders(BaseHTTPMiddleware):
    async def dispatch(self, request: Request, call_next: RequestResponseEndpoint) -> Response:
        response = await call_next(request)
        response.headers["Content-Security-Policy"] = CSP
        response.headers["X-Content-Type-Options"] = "nosniff"
        response.headers["Referrer-Policy"] = "no-referrer"
        response.headers["X-Frame-Options"] = "DENY"
        if not request.url.path.startswith("/static/"):
            response.headers["Cache-Control"] = "no-store"
        return response


class BadRequest(Exception):
    """A filter or search the page cannot use: shown on the page, with how to fix it."""


def _field(request: Request, name: str) -> str | None:
    value = request.query_params.get(name, "").strip()
    if not value:
        return None
    if len(value) > MAX_FIELD_CHARS or any(ord(c) < 32 for c in value):
        raise BadRequest(f"{name}: at most {MAX_FIELD_CHARS} characters, no control characters")
    return value


def default_since(request: Request) -> str | None:
    """The first day shown when the query names no days (the last :data:`DEFAULT_DAYS` days); None when it names
    one, or cleared them (all time)."""
    if "since" in request.query_params or "until" in request.query_params:
        return None
    return (dt.date.today() - dt.timedelta(days=DEFAULT_DAYS)).isoformat()


def filters_of(request: Request) -> Filters:
    """The chain page's filters from the query (days local, as the person typed them)."""
    since, until = _field(request, "since") or default_since(request), _field(request, "until")
    try:
        since = utc_bound(parse_day(since, "since") or "") if since else None
        until = utc_bound(parse_day(until, "until") or "", end_of_day=True) if until else None
    except (EdcBenchError, ValueError, OverflowError) as exc:
        raise BadRequest(str(exc)) from None
    if since and until and since > until:
        raise BadRequest("since is after until: give the earlier day first")
    simulated = request.query_params.get("simulated") == "1"
    return Filters(since=since, until=until, station=_field(request, "station"), variant=_field(request, "pump"),
                   operator=_field(request, "technician"), simulated=None if simulated else False,
                   shop=_field(request, "shop"))


def csv_response(rows: Iterable[Sequence[object]], columns: Sequence[str], name: str) -> Response:
    """A table as a CSV download (cells a spreadsheet would read as a formula are quoted as text)."""
    out = io.StringIO()
    writer = csv.writer(out)
    writer.writerow(columns)
    for row in rows:
        writer.writerow([_cell(value) for value in row])
    return Response(out.getvalue(), media_type="text/csv; charset=utf-8",
                    headers={"Content-Disposition": f'attachment; filename="{name}.csv"'})


def _cell(value: object) -> object:
    if isinstance(value, str) and value[:1] in ("=", "+", "-", "@", "\t", "\r"):
        return "'" + value  # a spreadsheet opens it as text, not a formula
    return "" if value is None else value


def _rate(value: float | None) -> str:
    return "-" if value is None else f"{value * 100:.1f} %"


class _Site:
    """The application's state and its pages: one method per route."""

    def __init__(self, config: WebConfig, sessions: Sessions, opener: Callable[[str], HistoryStore]) -> None:
        self.config, self.sessions, self.opener = config, sessions, opener
        self.shared: list[HistoryStore] = []  # a station's SQLite: one store every session reads
        self.shared_lock = threading.Lock()
        self.throttle = SignInThrottle()
        self.reports = ReportDrawer()
        # every value escaped, whatever a template's name ends in (ids and names are the technicians' text)
        self.templates = Jinja2Templates(env=jinja2.Environment(loader=jinja2.FileSystemLoader(HERE / "templates"),
                                                                autoescape=True))
        self.templates.env.filters.update(local=lambda value: local_text(value, empty="never"), rate=_rate)

    def render(self, request: Request, name: str, session: Session | None, status: int = 200,
               **context: object) -> Response:
        return self.templates.TemplateResponse(request, name, {"session": session, "sqlite": self.config.is_sqlite,
                                                               **context}, status_code=status)

    def signed_in(self, request: Request) -> Session | None:
        return self.sessions.get(request.cookies.get(SESSION_COOKIE))

    @staticmethod
    def to_signin(request: Request) -> Response:
        target = request.url.path + (f"?{request.url.query}" if request.url.query else "")
        response = RedirectResponse(f"/signin?next={quote(target, safe='')}", status_code=303)
        response.delete_cookie(SESSION_COOKIE)
        return response

    def page(self, handler: Callable[[Request, Session], Response]) -> Callable[[Request], Response]:
        """A page only a signed-in person sees (else the sign-in form); its errors said on the page."""
        def endpoint(request: Request) -> Response:
            session = self.signed_in(request)
            if session is None:
                return self.to_signin(request)
            try:
                with session.lock:  # one request at a time per session: its connection is not shared
                    return handler(request, session)
            except BadRequest as exc:
                return self.render(request, "error.html", session, 400, message=str(exc))
            except EdcBenchError as exc:  # the history's own one-line words (a login refused names who may)
                return self.render(request, "error.html", session, 403, message=str(exc))
        return endpoint

    # -- sign-in ----------------------------------------------------------------------------------------------

    def signin_form(self, request: Request, message: str = "", status: int = 200) -> Response:
        token = secrets.token_urlsafe(32)
        response = self.render(request, "signin.html", None, status, csrf=token, message=message,
                               next=_local_next(request.query_params.get("next")))
        response.set_cookie(SIGNIN_COOKIE, token, httponly=True, secure=self.config.secure_cookies,
                            samesite="strict", max_age=15 * 60)
        return response

    def signin_page(self, request: Request) -> Response:
        return self.signin_form(request)

    async def signin(self, request: Request) -> Response:
        form = await request.form()
        token, cookie = str(form.get("csrf", "")), request.cookies.get(SIGNIN_COOKIE, "")
        if not token or not cookie or not secrets.compare_digest(token.encode(), cookie.encode()):
            return self.signin_form(request, "the form had expired or did not come from this page: sign in again",
                                    403)
        login, password = str(form.get("login", "")).strip()[:MAX_FIELD_CHARS], str(form.get("password", ""))
        session = self._open_sqlite(login, password) if self.config.is_sqlite else self._open_login(login, password)
        if isinstance(session, str):
            return self.signin_form(request, session, 403)
        response = RedirectResponse(_local_next(str(form.get("next", ""))) or "/chain", status_code=303)
        response.set_cookie(SESSION_COOKIE, session.id, httponly=True, secure=self.config.secure_cookies,
                            samesite="strict")
        response.delete_cookie(SIGNIN_COOKIE)
        return response

    def _open_sqlite(self, name: str, token: str) -> Session | str:
        """A station's SQLite: the access token it printed; the name is only shown."""
        if not self.throttle.allowed(""):
            return "too many failed sign-ins: wait a few minutes, then try again"
        if not self.config.token or not secrets.compare_digest(token.encode(), self.config.token.encode()):
            self.throttle.failed("")
            return "wrong access token: use the one 'edc-bench web' printed when it started"
        with self.shared_lock:  # two first sign-ins at once open one store
            if not self.shared:
                self.shared.append(self.opener(self.config.url))
        name = "".join(c for c in name if ord(c) >= 32)
        return self.sessions.start(name or "station", self.shared[0], owns_store=False)

    def _open_login(self, login: str, password: str) -> Session | str:
        """The chain's PostgreSQL: a connection as the person's own login (its role decides what it reads).

        A password is required: without one the database driver would take the server's own (PGPASSWORD,
        ~/.pgpass, which docs/shop-network.md sets up for the owner's and the stations' logins), and anyone
        typing that login would be signed in as it."""
        if not login or not password or any(ord(c) < 32 for c in login):
            return "give your database login and its password"
        if not self.throttle.allowed(login):
            return "too many failed sign-ins for this login: wait a few minutes, then try again"
        url = sa.engine.make_url(self.config.url).set(username=login, password=password or None)
        try:
            store = self.opener(url.render_as_string(hide_password=False))
        except RevisionMismatch as exc:  # the login was accepted: the history is another edc-bench's revision
            return f"signed in, but this history cannot be read here: {exc}"
        except EdcBenchError:
            self.throttle.failed(login)
            return ("sign-in refused: the database did not accept this login and password, or this login may not "
                    "read the history")
        return self.sessions.start(login, store)

    async def signout(self, request: Request) -> Response:
        session = self.signed_in(request)
        form = await request.form()
        if session is None:
            return self.to_signin(request)
        if not secrets.compare_digest(str(form.get("csrf", "")).encode(), session.csrf.encode()):
            return self.render(request, "error.html", session, 403,
                               message="sign-out refused: the form did not come from this page")
        self.sessions.end(session.id)
        response = RedirectResponse("/signin", status_code=303)
        response.delete_cookie(SESSION_COOKIE)
        return response

    # -- pages ------------------------------------------------------------------------------------------------

    @staticmethod
    def home(request: Request) -> Response:
        return RedirectResponse("/chain", status_code=303)

    def chain(self, request: Request, session: Session) -> Response:
        try:
            filters = filters_of(request)
        except BadRequest as exc:
            return self.render(request, "chain.html", session, 400, summary=None, chart=None, message=str(exc),
                               query=request.query_params, since=None)
        summary = chain_summary(session.store, filters)
        return self.render(request, "chain.html", session, summary=summary, since=default_since(request),
                           days=DEFAULT_DAYS, chart=charts.tests_per_day(summary.per_day, period=summary.period),
                           message="", query=request.query_params)

    def chain_csv(self, request: Request, session: Session) -> Response:
        summary = chain_summary(session.store, filters_of(request))
        tables: dict[str, tuple[Sequence[str], Iterable[Sequence[object]]]] = {
            "verdicts": (("verdict", "tests"), summary.verdicts),
            "invalid": (("where to look", "tests"), summary.invalid_areas),
            "days": ((summary.period, "station", "tests"), ((d.day, d.station, d.tests) for d in summary.per_day)),
            "stations": (("station", "shop", "tests", "latest test", "latest self-check", "quiet"),
                         ((s.station, s.shop or "", s.tests, local_text(s.last_test_at), local_text(s.last_check_at),
                           s.quiet) for s in summary.stations)),
            "shops": (("shop", "stations", "tests"), summary.shops),
        }
        table = str(request.path_params.get("table", ""))
        if table not in tables:
            raise BadRequest(f"no table {table!r}: verdicts, invalid, days or stations")
        columns, rows = tables[table]
        return csv_response(rows, columns, table)

    def rigs(self, request: Request, session: Session) -> Response:
        station = _field(request, "station")
        # charts for a few rigs at once; a chain's hundred are a table (each rig's trend from its last quarter),
        # each rig's chart on its own page
        shown = views.rig_healths(session.store, station, views.CHECKS_SHOWN if station else views.OVERVIEW_CHECKS)
        charted = station is not None or len(shown) <= CHARTS_AT_ONCE
        if charted and station is None:
            shown = views.rig_healths(session.store)
        return self.render(request, "rigs.html", session, station=station, charted=charted,
                           rigs=[(r, charts.drift_chart(r.station, list(r.drifts)) if charted else None)
                                 for r in shown])

    def rigs_csv(self, request: Request, session: Session) -> Response:
        rows = [(r.station, local_text(c.checked_at), c.verdict, c.causes, c.checked_by, *(d for _, d, _ in c.drift))
                for r in views.rig_healths(session.store, _field(request, "station")) for c in r.checks]
        columns = ("station", "checked at", "verdict", "causes", "checked by",
                   *(f"{name} drift" for name, _, _ in views.COLUMNS))
        return csv_response(rows, columns, "rig-checks")

    def valves(self, request: Request, session: Session) -> Response:
        text = _field(request, "q")
        return self.render(request, "valves.html", session, q=text or "",
                           found=views.search(session.store, text) if text else [])

    def valve(self, request: Request, session: Session) -> Response:
        valve_id = _field(request, "id")
        if valve_id is None:
            raise BadRequest("which valve? search for its id or its pump's serial")
        rows = views.valve_tests(session.store, valve_id)
        shown = visits(r.row for r in rows if r.state == "standing")
        trustworthy = [v for v in shown if v.decision != "INVALID" and not v.last.simulated]
        records = self.config.records_dir
        reports = {v.last.id for v in shown if record_folder(records, str(v.last.record_dir))}
        return self.render(request, "valve.html", session, valve_id=valve_id, rows=rows, visits=shown,
                           chart=charts.valve_trend(trustworthy, valve_id) if trustworthy else None,
                           audit=session.store.audit(valve_id), reports=reports)

    def valve_csv(self, request: Request, session: Session) -> Response:
        columns = ("id", "state", "started_at", "valve_id", "pump_serial", "variant", "verdict", "decision", "af_v",
                   "a1_v_s_per_mm", "af_rel", "a1_rel", "distance", "station", "operator", "invalid_area")
        rows = views.valve_tests(session.store, _field(request, "id") or "")
        return csv_response(([r.state if c == "state" else getattr(r.row, c) for c in columns] for r in rows), columns,
                            "valve")

    def report(self, request: Request, session: Session) -> Response:
        row = views.test_row(session.store, int(request.path_params.get("test_id", 0)))
        if row is None:
            raise BadRequest("no such test in the history")
        if not views.stands(session.store, int(row.id)):
            return self.render(request, "error.html", session, 409, message="this row is not the test as it stands "
                               "(withdrawn, or indexed again with other content): its report is not drawn. The "
                               "valve's page shows what stands")
        records = self.config.records_dir
        folder = record_folder(records, str(row.record_dir))
        if folder is None:
            return self.render(request, "error.html", session, 403, message="this test's record is not in the "
                               "records folder this page serves: its report is not shown")
        retest_row = views.retest_of(session.store, str(row.record_dir))
        retest_folder = None if retest_row is None else record_folder(records, str(retest_row.record_dir))
        retest = None if retest_folder is None else IndexedRecord(retest_folder, retest_row.record_sha256)
        note = f"history test {row.id}" + (f", chain {row.row_hash[:16]}" if row.row_hash else "")
        try:
            pdf = self.reports.pdf(IndexedRecord(folder, row.record_sha256), note, retest)
        except ReportRefused as exc:
            return self.render(request, "error.html", session, 409, message=str(exc))
        except ReportBusy as exc:
            response = self.render(request, "error.html", session, 503, message=str(exc))
            response.headers["Retry-After"] = "5"
            return response
        return Response(pdf, media_type="application/pdf",
                        headers={"Content-Disposition": f'inline; filename="report-{row.id}.pdf"'})

    def models(self, request: Request, session: Session) -> Response:
        current, every = views.models(session.store)
        return self.render(request, "models.html", session, current=current, every=every)

    def models_csv(self, request: Request, session: Session) -> Response:
        columns = ("id", "station", "model_name", "model_sha256", "adopted_by", "adopted_at")
        _, every = views.models(session.store)
        return csv_response(([*(getattr(row, c) for c in columns), *row.evaluation_cells()] for row in every),
                            (*columns, *views.Adoption.EVALUATION_COLUMNS), "adoptions")

    def close(self) -> None:
        self.sessions.close_all()
        for store in self.shared:
            store.close()


def create_app(config: WebConfig, sessions: Sessions | None = None,
               open_store: Callable[[str], HistoryStore] | None = None) -> Starlette:
    """The application for ``config`` (``sessions``: the tests' own clock; ``open_store``: how a URL is opened)."""
    site = _Site(config, sessions if sessions is not None else Sessions(config.idle_minutes * 60,
                                                                         config.max_hours * 3600),
                 open_store or (lambda url: HistoryStore(url, must_exist=True, warn=lambda _problem: None)))
    routes = [
        Route("/", site.home),
        Route("/signin", site.signin_page, methods=["GET"]),
        Route("/signin", site.signin, methods=["POST"]),
        Route("/signout", site.signout, methods=["POST"]),
        *(Route(path, site.page(handler)) for path, handler in (
            ("/chain", site.chain), ("/chain/{table}.csv", site.chain_csv), ("/rigs", site.rigs),
            ("/rigs.csv", site.rigs_csv), ("/valves", site.valves), ("/valve", site.valve),
            ("/valve.csv", site.valve_csv), ("/report/{test_id:int}", site.report), ("/models", site.models),
            ("/models.csv", site.models_csv))),
        Mount("/static", StaticFiles(directory=str(HERE / "static")), name="static"),
    ]

    @contextlib.asynccontextmanager
    async def lifespan(_app: Starlette) -> AsyncIterator[None]:
        yield
        site.close()

    app = Starlette(routes=routes, middleware=[Middleware(_SecurityHeaders)], lifespan=lifespan)
    app.state.sessions = site.sessions
    return app


def settle_for_serving() -> None:
    """Make ready to serve: the plotting library loaded and a chart drawn, and every object there is then moved out
    of the garbage collector's way (:func:`gc.freeze`). A full collection otherwise walks all of matplotlib's and
    SQLAlchemy's objects during a request: 50-100 ms added to one request in five or six (measured on the chain
    page of a million tests). The server (``edc-bench web``) and its benchmark both call it."""
    charts.warm()
    gc.collect()
    gc.freeze()


def _local_next(target: str | None) -> str:
    """A redirect target only if it is a page of this site (never another host: '//host', '/\\host')."""
    if not target or not target.startswith("/") or target.startswith(("//", "/\\")) or any(c in target for c in "\r\n"):
        return ""
    return target
