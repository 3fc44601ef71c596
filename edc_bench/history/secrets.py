"""A history URL's password, never shown: URLs masked for people, and text scrubbed where a password can leak.

A shop's PostgreSQL URL may carry the login's password
(``postgresql+psycopg://station:PASSWORD@host/edc``, ``user@server:PASSWORD@host``
as Azure names logins, or ``?password=`` after it). Every URL edc-bench shows
goes through :func:`shown_url`, as SQLAlchemy renders URLs with
``hide_password=True``; text that may quote a password (a driver's message)
goes through :func:`redact`; and the CLI's standard output and error go
through a :class:`RedactingStream`, which removes a known password where it
can be a leak (inside a URL, on a line a driver or a traceback wrote) but
leaves a listing's words alone: a password that is also a word ("PASS")
does not blank every PASS verdict. Pure text: no SQLAlchemy import, so
checking the history before a test costs nothing.
"""

from __future__ import annotations

import os
import re
import threading
from collections.abc import Iterable, Iterator
from urllib.parse import quote, quote_plus, unquote, unquote_plus

#: What stands in for a password.
MASK = "***"

_SCHEME = r"\b[A-Za-z][A-Za-z0-9+.\-]*://"
# In running text: scheme://USER:PASSWORD@HOST[/DB][?KEY=...]. The user as SQLAlchemy reads it ('@' included:
# Azure's user@server; no ':' or '/'); the password without blanks, up to the first '@' that a host follows (then a
# database name and option names without '@'), so that a raw '@' inside a password is masked with it.
_USERINFO = re.compile(r"(?P<head>" + _SCHEME + r"[^\s:/@]*(?:@[^\s:/@]*)*):(?P<secret>\S*?)"
                       r"@(?=[^\s@/?#'\"]*(?:/[^\s@?#'\"]*)?(?:[#\s'\",;)\]]|\?[^\s=&@]*=|$))")
# A URL alone (--db's value, EDC_BENCH_HISTORY_URL), as SQLAlchemy parses a whole string: the user and the
# password may hold blanks too; on one line.
_OPTION = r"[^=&@\n]*=[^&\n]*"
_WHOLE_URL = re.compile(r"(?P<head>[A-Za-z][A-Za-z0-9+.\-]*://[^:/\n]*):(?P<secret>.*?)"
                        rf"@[^@/?\n]*(?:/[^@?\n]*)?(?:\?(?:{_OPTION}(?:&{_OPTION})*)?)?\n?")
# ?password=PASSWORD or &password=PASSWORD (libpq's keyword, which psycopg takes from the URL's query); a value
# masked already stays as it is, so masking twice leaves the text after it ('***: connection failed') alone
_QUERY_PASSWORD = re.compile(r"(?i)(?P<head>[?&]password=)(?P<secret>\*\*\*(?=:?(?:[\s&'\"]|$))|[^&\s'\"]*)")
# ... and in a URL alone, up to the next option
_WHOLE_QUERY_PASSWORD = re.compile(r"(?i)[?&]password=(?P<secret>[^&\n]*)")


def shown_url(text: str) -> str:
    """``text`` (a URL, or a message quoting one) with every password in it replaced by ``***``.

    Every form SQLAlchemy reads is masked: ``user:PASSWORD@``, ``user@server:PASSWORD@`` (Azure), a password
    with ``%``-escapes or raw ``:`` and ``/`` in it, one with a raw ``@`` (masked up to the host, though SQLAlchemy
    would misread it: see :func:`raw_at_in_password`), and ``?password=``. A password with blanks is masked in a
    URL alone; in a message, :func:`redact` with the URL's :func:`secrets_of` removes it.
    """
    whole = _WHOLE_URL.fullmatch(text)
    if whole is not None:  # a URL alone: its password may hold blanks
        text = f"{whole['head']}:{MASK}@{text[whole.end('secret') + 1:]}"
        return _QUERY_PASSWORD.sub(lambda m: f"{m['head']}{MASK}", text)
    return _masked_in_text(text)


def _masked_in_text(text: str) -> str:
    """``text`` with the password of every URL in it masked (a password without blanks: see :data:`_USERINFO`)."""
    text = _USERINFO.sub(lambda m: f"{m['head']}:{MASK}@", text)
    return _QUERY_PASSWORD.sub(lambda m: f"{m['head']}{MASK}", text)


def raw_at_in_password(url: str) -> bool:
    """Whether ``url``'s password holds a raw ``@``, which SQLAlchemy reads as the password's end (what follows
    it becomes the host, shown in the driver's messages); written ``%40`` it is read as it is meant."""
    whole = _WHOLE_URL.fullmatch(url)
    return whole is not None and "@" in whole["secret"]


def _passwords(text: str) -> Iterator[str]:
    """The passwords as written in ``text``: of every URL in it, and of the URL that runs to its end."""
    for match in _USERINFO.finditer(text):
        yield match["secret"]
    for match in _QUERY_PASSWORD.finditer(text):
        yield match["secret"]
    for start in re.finditer(_SCHEME, text):  # '--db=URL' or a URL alone: blanks in the password too
        whole = _WHOLE_URL.fullmatch(text, start.start())
        if whole is not None:
            yield whole["secret"]
        yield from (m["secret"] for m in _WHOLE_QUERY_PASSWORD.finditer(text, start.start()))


def secrets_of(url: str | None) -> list[str]:
    """The passwords ``url`` carries, in every form a message may quote them (empty: none).

    As written, percent-decoded (as SQLAlchemy and the query's parser read them), and percent-encoded again
    (as SQLAlchemy renders a URL with its password); the longest first, so that a shorter form inside a longer
    one is not left behind. ``url`` may also be text holding a URL (``--db=URL``).
    """
    if not url:
        return []
    forms: set[str] = set()
    for secret in _passwords(url):
        if not secret or secret == MASK:
            continue
        for decoded in {secret, unquote(secret), unquote_plus(secret)}:
            forms.update((decoded, quote(decoded, safe=" +"), quote_plus(decoded)))
    return sorted((form for form in forms if form), key=len, reverse=True)


def known_secrets(*urls: str | None) -> list[str]:
    """The passwords of ``urls`` and of ``EDC_BENCH_HISTORY_URL``."""
    found = {secret for url in (*urls, os.environ.get("EDC_BENCH_HISTORY_URL")) for secret in secrets_of(url)}
    return sorted(found, key=len, reverse=True)


#: Secrets shorter than this are masked inside URLs only: replacing 'ab' wherever it stands would garble the text.
MIN_SCRUBBED_CHARS = 4


def _as_word(secret: str) -> re.Pattern[str]:
    """``secret`` where it stands on its own: not the 'pass' of 'password' (its letters run on), but the 'pass'
    of ``password=pass`` or ``"pass"``."""
    head = r"(?<!\w)" if re.match(r"\w", secret) else ""
    tail = r"(?!\w)" if re.search(r"\w\Z", secret) else ""
    return re.compile(head + re.escape(secret) + tail)


def redact(text: str, secrets: Iterable[str]) -> str:
    """``text`` (a driver's message, an error) with URLs' passwords masked and each of ``secrets`` replaced
    by ``***`` wherever it stands as a word of its own."""
    text = _masked_in_text(text)
    for secret in secrets:
        if len(secret) >= MIN_SCRUBBED_CHARS:
            text = _as_word(secret).sub(MASK, text)
    return text


# A URL that can carry a password: with a user (scheme://...@) or a password in its query.
_CREDENTIAL_URL = re.compile(_SCHEME + r"(?:[^\s@]*@|\S*[?&]password=)", re.IGNORECASE)
# ... as one token of a line (up to a blank)
_CREDENTIAL_URL_TOKEN = re.compile(r"\S*(?:" + _CREDENTIAL_URL.pattern + r")\S*", re.IGNORECASE)
# Lines where a password can leak: a database's messages (edc-bench's "history database URL: ...", the driver's,
# SQLAlchemy's), an exception or a warning, a line about the history's URL or quoting a URL (argparse's errors
# quote the arguments: a password with a blank is not masked as part of the URL there).
_LEAK_LINE = re.compile(
    r"(?i)history database|EDC_BENCH_HISTORY_URL|passw(?:or)?d|\b(?:dis)?connect(?:s|ed|ing|ion|ions)?\b|conninfo|"
    r"\bdsn\b|authenticat|psycopg|libpq|sqlalchemy|sqlstate|fe_sendauth|\bfatal\b|\b(?:host|hostaddr|user|dbname|"
    r"port|service)=|server at|resolve host|translate host|(?-i:\w(?:Error|Exception|Warning)\b)|" + _SCHEME)
# The start of a traceback (and the CLI's line before one): whatever follows on the stream is scrubbed too.
_TRACEBACK = re.compile(r"Traceback \(most recent call last\)|internal error:|Exception ignored in")


class RedactingStream:
    """A text stream that writes through to ``stream`` with known passwords removed where they can leak.

    The CLI puts its standard output and error behind one while a password is known (in its arguments or
    ``EDC_BENCH_HISTORY_URL``), from before its arguments are parsed (argparse quotes them in its errors): whatever
    a library prints (a driver's message, a traceback) cannot show it. Each line is written once it is whole
    (or flushed), and in it: every URL's password is masked; a secret inside a URL that can hold a
    password is replaced wherever it stands in it; and on a line where a password can leak (a database's or
    driver's message, an exception, a warning, a line quoting a URL, anything after a traceback
    starts) a secret is replaced where it stands as a word of its own. Elsewhere (a listing, a report) a
    secret that is also a word, such as ``PASS``, stays: it cannot be told from the word, and blanking it would
    garble every verdict. Everything else (``isatty``, ``fileno``, ``encoding``...) is the stream's own.
    """

    def __init__(self, stream: object, secrets: Iterable[str]) -> None:
        self._stream = stream
        self._secrets = [secret for secret in secrets if len(secret) >= MIN_SCRUBBED_CHARS]
        self._words = [_as_word(secret) for secret in self._secrets]
        self._pending = ""  # the start of a line not yet ended
        self._in_traceback = False
        self._lock = threading.RLock()  # threads' lines stay whole; a signal handler's write may re-enter

    def write(self, text: str) -> int:
        with self._lock:
            if not self._pending and text.endswith("\n"):  # whole lines, as nearly every write is
                whole = text
            else:
                text_so_far = self._pending + text
                cut = text_so_far.rfind("\n") + 1
                whole, self._pending = text_so_far[:cut], text_so_far[cut:]
            if whole:
                lines = whole.splitlines(keepends=True)
                self._stream.write("".join(self._scrub(line) for line in lines))  # type: ignore[attr-defined]
        return len(text)

    def writelines(self, lines: Iterable[str]) -> None:
        for line in lines:
            self.write(line)

    def flush(self) -> None:
        """Write the line begun (a prompt, a progress line) as it stands, then flush the stream."""
        with self._lock:
            if self._pending:
                self._stream.write(self._scrub(self._pending))  # type: ignore[attr-defined]
                self._pending = ""
            self._stream.flush()  # type: ignore[attr-defined]

    def _scrub(self, line: str) -> str:
        """One line as it may be shown."""
        line = _masked_in_text(line)
        if not self._secrets:
            return line
        line = _CREDENTIAL_URL_TOKEN.sub(lambda m: self._scrub_all(m[0]), line)
        if _TRACEBACK.search(line):
            self._in_traceback = True
        if self._in_traceback or _LEAK_LINE.search(line):
            for word in self._words:
                line = word.sub(MASK, line)
        return line

    def _scrub_all(self, token: str) -> str:
        for secret in self._secrets:
            token = token.replace(secret, MASK)
        return token

    def __getattr__(self, name: str) -> object:
        return getattr(self._stream, name)

__all__ = ["MASK", "RedactingStream", "known_secrets", "raw_at_in_password", "redact", "secrets_of", "shown_url"]
