"""Who is signed in: sessions held on the server, each with its own history connection, its CSRF token and its
expiry (the cookie carries only a random id)."""

from __future__ import annotations

import secrets
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field

from edc_bench.history.store import HistoryStore


@dataclass
class Session:
    """One signed-in person: the history as their login reads it, and their forms' token."""

    id: str
    login: str
    store: HistoryStore
    csrf: str
    started_s: float
    seen_s: float
    #: whether ending the session closes ``store`` (a station's SQLite is one store that every session shares)
    owns_store: bool = True
    lock: threading.Lock = field(default_factory=threading.Lock)


class Sessions:
    """The signed-in sessions, expired after ``idle_s`` without a request or ``max_s`` after sign-in.

    Parameters
    ----------
    idle_s, max_s : float
        The idle and the absolute limits (seconds).
    clock : callable
        Monotonic seconds (tests pass their own).
    """

    def __init__(self, idle_s: float = 30 * 60, max_s: float = 12 * 3600,
                 clock: Callable[[], float] = time.monotonic) -> None:
        self.idle_s, self.max_s, self._clock = idle_s, max_s, clock
        self._sessions: dict[str, Session] = {}
        self._lock = threading.Lock()

    def start(self, login: str, store: HistoryStore, owns_store: bool = True) -> Session:
        """A new session for ``login`` reading ``store`` (closed when the session ends, if ``owns_store``)."""
        self.sweep()
        now = self._clock()
        session = Session(secrets.token_urlsafe(32), login, store, secrets.token_urlsafe(32), now, now, owns_store)
        with self._lock:
            self._sessions[session.id] = session
        return session

    def sweep(self) -> None:
        """End every expired session and close its connection (a session abandoned without signing out would
        otherwise hold its database connection until the server stops)."""
        now = self._clock()
        with self._lock:
            expired = [s for s in self._sessions.values()
                       if now - s.seen_s > self.idle_s or now - s.started_s > self.max_s]
            for session in expired:
                del self._sessions[session.id]
        for session in expired:
            if session.owns_store:
                session.store.close()

    def __len__(self) -> int:
        return len(self._sessions)

    def get(self, session_id: str | None) -> Session | None:
        """The live session of a cookie's id (None: none, or expired: then ended)."""
        if not session_id:
            return None
        now = self._clock()
        with self._lock:
            session = self._sessions.get(session_id)
            if session is None:
                return None
            if now - session.seen_s > self.idle_s or now - session.started_s > self.max_s:
                del self._sessions[session_id]
                expired = session
            else:
                session.seen_s = now
                return session
        if expired.owns_store:
            expired.store.close()
        return None

    def end(self, session_id: str) -> None:
        """Sign out: the session and its connection closed."""
        with self._lock:
            session = self._sessions.pop(session_id, None)
        if session is not None and session.owns_store:
            session.store.close()

    def close_all(self) -> None:
        """End every session (the server stops)."""
        for session_id in list(self._sessions):
            self.end(session_id)


class SignInThrottle:
    """Failed sign-ins per login: after ``limit`` within ``window_s`` the login is refused until the window has
    passed (a password guessed at the form's speed is guessed at a few a minute at most)."""

    def __init__(self, limit: int = 5, window_s: float = 300.0, clock: Callable[[], float] = time.monotonic) -> None:
        self.limit, self.window_s, self._clock = limit, window_s, clock
        self._failures: dict[str, list[float]] = {}
        self._lock = threading.Lock()

    def _recent(self, login: str) -> list[float]:
        now = self._clock()
        recent = [t for t in self._failures.get(login, []) if now - t < self.window_s]
        if recent:
            self._failures[login] = recent
        else:
            self._failures.pop(login, None)
        return recent

    def allowed(self, login: str) -> bool:
        """Whether ``login`` may try now."""
        with self._lock:
            return len(self._recent(login)) < self.limit

    def failed(self, login: str) -> None:
        """Count a failed sign-in of ``login``."""
        with self._lock:
            self._failures[login] = [*self._recent(login), self._clock()]
