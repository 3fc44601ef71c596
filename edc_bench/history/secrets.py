"""A history URL's password, never shown: URLs masked for people, and any text scrubbed of the password.

A shop's PostgreSQL URL may carry the login's password
(``postgresql+psycopg://station:PASSWORD@host/edc``, or ``?password=`` after
it). Every URL edc-bench shows goes through :func:`shown_url`, as SQLAlchemy
renders URLs with ``hide_password=True``; and text that may quote a URL (a
driver's message, a warning) goes through :func:`redact`, which removes the
password wherever it stands. Pure text: no SQLAlchemy import, so checking the
history before a test costs nothing.
"""

from __future__ import annotations

import os
import re
from collections.abc import Iterable
from urllib.parse import unquote

#: What stands in for a password.
MASK = "***"

# scheme://user:PASSWORD@ as SQLAlchemy reads it: the user holds no ':' or '/', the password anything up to the first
# '@' ('/' and quotes included), on one line
_USERINFO = re.compile(r"(?P<head>\b[A-Za-z][A-Za-z0-9+.\-]*://[^:/@\s]*):(?P<secret>[^@\n]*)@")
# ?password=PASSWORD or &password=PASSWORD (libpq's keyword, which psycopg takes from the URL's query)
_QUERY_PASSWORD = re.compile(r"(?i)(?P<head>[?&]password=)(?P<secret>[^&#\s'\"]*)")


def shown_url(text: str) -> str:
    """``text`` (a URL, or a message quoting one) with every password in it replaced by ``***``."""
    text = _USERINFO.sub(lambda m: f"{m['head']}:{MASK}@", text)
    return _QUERY_PASSWORD.sub(lambda m: f"{m['head']}{MASK}", text)


def secrets_of(url: str | None) -> list[str]:
    """The passwords ``url`` carries, as written and percent-decoded (empty: none)."""
    if not url:
        return []
    found = [m["secret"] for m in _USERINFO.finditer(url)] + [m["secret"] for m in _QUERY_PASSWORD.finditer(url)]
    return sorted({form for secret in found if secret for form in (secret, unquote(secret)) if form},
                  key=len, reverse=True)  # the longest first: a decoded form inside the written one is not left


def known_secrets(*urls: str | None) -> list[str]:
    """The passwords of ``urls`` and of ``EDC_BENCH_HISTORY_URL``."""
    found = {secret for url in (*urls, os.environ.get("EDC_BENCH_HISTORY_URL")) for secret in secrets_of(url)}
    return sorted(found, key=len, reverse=True)


#: Secrets shorter than this are masked inside URLs only: replacing 'ab' wherever it stands would garble the text.
MIN_SCRUBBED_CHARS = 4


def redact(text: str, secrets: Iterable[str]) -> str:
    """``text`` with URLs masked (:func:`shown_url`) and each of ``secrets`` replaced by ``***`` wherever it is."""
    text = shown_url(text)
    for secret in secrets:
        if len(secret) >= MIN_SCRUBBED_CHARS:
            text = text.replace(secret, MASK)
    return text


class RedactingStream:
    """A text stream that writes through to ``stream`` with ``secrets`` replaced by ``***``.

    The CLI puts its standard output and error behind one while a password is known (given by ``--db`` or
    ``EDC_BENCH_HISTORY_URL``): whatever a library prints (a driver's message, a traceback) cannot show it.
    Everything else (``isatty``, ``fileno``, ``encoding``...) is the stream's own.
    """

    def __init__(self, stream: object, secrets: Iterable[str]) -> None:
        self._stream = stream
        self._secrets = list(secrets)

    def write(self, text: str) -> int:
        self._stream.write(redact(text, self._secrets))  # type: ignore[attr-defined]
        return len(text)

    def writelines(self, lines: Iterable[str]) -> None:
        for line in lines:
            self.write(line)

    def __getattr__(self, name: str) -> object:
        return getattr(self._stream, name)


__all__ = ["MASK", "RedactingStream", "known_secrets", "redact", "secrets_of", "shown_url"]
