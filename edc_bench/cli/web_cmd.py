"""``edc-bench web``: the history in a browser, read-only (docs/web.md)."""

from __future__ import annotations

import argparse
import errno
import ipaddress
import secrets
import socket
import sys
from pathlib import Path

from edc_bench.cli.common import add_history_db_argument, given_path, port_number, positive_int

#: Hosts a station's SQLite history is served on without --allow-remote.
LOOPBACK = ("127.0.0.1", "::1", "localhost")


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Register the command."""
    p = sub.add_parser(
        "web", help="the chain's history in a browser: verdicts, rigs' health, every valve's story",
        description="Serve the history (the station's SQLite, or the chain's PostgreSQL named by --db or "
                    "EDC_BENCH_HISTORY_URL) as web pages, read-only. On PostgreSQL each person signs in with their "
                    "database login; a station's SQLite is served on 127.0.0.1 only, to whoever has the access "
                    "token printed at start (docs/web.md).")
    add_history_db_argument(p)
    p.add_argument("--host", default="127.0.0.1", help="address to listen on (default: 127.0.0.1, this PC only)")
    p.add_argument("--port", type=port_number, default=8080, help="port, 1 to 65535 (default: 8080)")
    p.add_argument("--records", type=given_path, default=Path("records"), metavar="DIR",
                   help="the records folder: a test's PDF report is served only from inside it (default: ./records)")
    p.add_argument("--allow-remote", action="store_true",
                   help="serve a station's SQLite history on an address other than this PC's (another PC then "
                        "signs in with the access token)")
    p.add_argument("--certfile", type=given_path, default=None, metavar="PEM",
                   help="serve HTTPS with this certificate (with --keyfile): needed for sign-in from other PCs, "
                        "whose browsers keep the secure session cookie only over HTTPS")
    p.add_argument("--keyfile", type=given_path, default=None, metavar="PEM", help="the certificate's private key")
    p.add_argument("--idle-minutes", type=positive_int, default=30,
                   help="a session ends after this many minutes without a page (default: 30)")
    p.add_argument("--token-file", type=given_path, default=None, metavar="FILE",
                   help="SQLite: read the access token from FILE instead of making a new one")
    p.set_defaults(run=run)


def _loopback(host: str) -> bool:
    if host in LOOPBACK:
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def run(args: argparse.Namespace) -> int:
    """Check the options, open the history once (its errors said before serving), and serve until Ctrl-C."""
    from edc_bench.errors import ConfigError
    from edc_bench.history.url import check_url, default_url
    from edc_bench.web.app import WebConfig

    if (args.certfile is None) != (args.keyfile is None):
        raise ConfigError("--certfile and --keyfile go together: give both, or neither for plain HTTP")
    for name, path in (("--certfile", args.certfile), ("--keyfile", args.keyfile)):
        if path is not None and not path.is_file():
            raise ConfigError(f"{name} {path}: no such file")
    if args.certfile is not None:  # loaded now, as the server would: a file that is no certificate is one line
        import ssl

        try:
            ssl.create_default_context(ssl.Purpose.CLIENT_AUTH).load_cert_chain(args.certfile, args.keyfile)
        except (ssl.SSLError, OSError) as exc:
            raise ConfigError(f"--certfile {args.certfile} --keyfile {args.keyfile}: not a certificate and its key "
                              f"in PEM ({exc}): give the server's certificate and private key") from None
    url = args.db or default_url()
    check_url(url, must_exist=True)
    config = WebConfig(url=url, records_dir=args.records.resolve() if args.records.is_dir() else None,
                       secure_cookies=True, idle_minutes=float(args.idle_minutes))
    if config.is_sqlite:
        if not _loopback(args.host) and not args.allow_remote:
            raise ConfigError(f"--host {args.host}: a station's SQLite history is served on 127.0.0.1 only; add "
                              "--allow-remote to serve it to other PCs (with --certfile/--keyfile: HTTPS)")
        if not _loopback(args.host) and not args.certfile:
            raise ConfigError("--allow-remote serves HTTPS only: give --certfile and --keyfile (over plain HTTP the "
                              "access token would cross the network readable)")
        token = _token(args.token_file)
        config = WebConfig(**{**config.__dict__, "token": token})
        from edc_bench.history.store import HistoryStore

        HistoryStore(url, must_exist=True).close()  # its problems said now, not at the first sign-in
    elif not args.certfile and not _loopback(args.host):
        print("edc-bench web: warning: plain HTTP to other PCs: their browsers will not keep the session cookie; "
              "serve HTTPS (--certfile, --keyfile) or put a TLS proxy in front (docs/web.md)", file=sys.stderr)
    if config.records_dir is None:
        print(f"edc-bench web: warning: no records folder {args.records}: reports will not be served (--records DIR)",
              file=sys.stderr)
    listening = _listening_socket(args.host, args.port)  # a port in use or a host not this PC's: said, not a URL
    scheme = "https" if args.certfile else "http"
    host = f"[{args.host}]" if ":" in args.host else args.host
    print(f"edc-bench web: serving {config.url if config.is_sqlite else _shown(url)} on {scheme}://{host}:{args.port}/"
          + (f"  access token: {config.token}" if config.is_sqlite else "  (sign in with your database login)"),
          flush=True)
    return _serve(config, args, listening)


def _shown(url: str) -> str:
    from edc_bench.history.secrets import shown_url

    return shown_url(url)


def _token(path: Path | None) -> str:
    from edc_bench.errors import ConfigError

    if path is None:
        return secrets.token_urlsafe(18)
    try:
        token = path.read_text(encoding="utf-8").strip()
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"--token-file {path}: cannot read it ({exc})") from None
    if len(token) < 16:
        raise ConfigError(f"--token-file {path}: the token is {len(token)} characters; give at least 16")
    return token


def _listening_socket(host: str, port: int) -> socket.socket:
    """The server's socket, bound and listening, or one line saying why it cannot be (before the URL is printed)."""
    from edc_bench.errors import ConfigError

    try:
        family, kind, proto, _, address = socket.getaddrinfo(host, port, type=socket.SOCK_STREAM,
                                                             flags=socket.AI_PASSIVE)[0]
    except (socket.gaierror, UnicodeError) as exc:
        raise ConfigError(f"--host {host}: not a host name or address this PC knows ({exc}); give 127.0.0.1 or "
                          "one of this PC's addresses") from None
    listening = socket.socket(family, kind, proto)
    try:
        listening.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        listening.bind(address)
        listening.listen(2048)
    except OSError as exc:
        listening.close()
        why = {errno.EADDRINUSE: "another program (or another edc-bench web) serves on it: give another --port",
               errno.EACCES: "this user may not use a port below 1024: give one from 1024 up",
               errno.EADDRNOTAVAIL: "the address is not this PC's: give 127.0.0.1 or one of this PC's addresses"}
        raise ConfigError(f"--host {host} --port {port}: cannot serve there ({exc.strerror}): "
                          f"{why.get(exc.errno or 0, 'give another --host or --port')}") from None
    return listening


def _serve(config: object, args: argparse.Namespace, listening: socket.socket) -> int:
    import uvicorn

    from edc_bench.web.app import create_app, settle_for_serving

    app = create_app(config)  # type: ignore[arg-type]
    settle_for_serving()
    server = uvicorn.Server(uvicorn.Config(app, log_level="warning",
                                           ssl_certfile=str(args.certfile) if args.certfile else None,
                                           ssl_keyfile=str(args.keyfile) if args.keyfile else None))
    with listening:
        server.run(sockets=[listening])
    return 0
