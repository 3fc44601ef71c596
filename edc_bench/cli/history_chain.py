"""``edc-bench history``'s chain actions: withdraw a test, a valve's audit trail, verify the indexed records, and
the owner's schema revisions and roles (docs/shop-network.md)."""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from collections.abc import Callable
from contextlib import AbstractContextManager
from typing import Any

from edc_bench.cli.common import given_path_text, identity, positive_int, print_quietly_if_closed
from edc_bench.history.rows import AuditEvent, ChainHead
from edc_bench.timefmt import local_column, local_text

#: The longest reason kept with a withdrawal.
MAX_WHY_CHARS = 2000


def add_chain_arguments(p: argparse.ArgumentParser) -> None:
    """The chain's flags, in a group of their own."""
    chain = p.add_argument_group("a shop's chain (docs/shop-network.md)")
    chain.add_argument("--withdraw", type=positive_int, default=None, metavar="TEST_ID",
                       help="withdraw a test (its id from the listing) with --why: it leaves listings, trends and "
                            "training; nothing is deleted (an engineer's login)")
    chain.add_argument("--why", default=None, metavar="TEXT", help="with --withdraw: why (kept in the audit trail)")
    chain.add_argument("--by", type=identity(), default=None, metavar="NAME",
                       help="with --withdraw: who withdraws (default: the login name)")
    chain.add_argument("--audit", type=identity(), default=None, metavar="VALVE_ID",
                       help="everything the history holds of one valve, in the order written: tests indexed, "
                            "findings, corrections and withdrawals, with who and when")
    chain.add_argument("--verify", action="store_true",
                       help="read every indexed record folder again and check the history's hash chain: list the "
                            "missing folders, those changed since they were first indexed, tests indexed again with "
                            "other content, and rows changed, deleted or put in by hand (exit 16 if any; --station: "
                            "one station's)")
    chain.add_argument("--heads", nargs="?", const="-", default=None, type=given_path_text, metavar="FILE",
                       help="print each chain's last row and hash (JSON) to keep outside the station; with --verify: "
                            "check that the history still holds the heads kept in FILE")
    chain.add_argument("--map-login", nargs="?", const="", default=None, metavar="LOGIN",
                       help="PostgreSQL, the owner's login: the database login LOGIN is station --station NAME (the "
                            "database writes that name into every test and rig self-check the login adds; a login "
                            "with no station may add none) and person --person NAME; without LOGIN: list every "
                            "login's mapping")
    chain.add_argument("--person", type=identity(), default=None, metavar="NAME",
                       help="with --map-login: the person the login is (named in its withdrawals and adoptions)")
    chain.add_argument("--shop", type=identity(), default=None, metavar="NAME",
                       help="with --map-login LOGIN --station NAME: the shop that station belongs to (the chain's "
                            "figures are counted by shop); with --summary or a listing: only that shop's stations")
    chain.add_argument("--rig", action="store_true",
                       help="the rig self-check's ledger: each reference valve registered, each 'edc-bench "
                            "rig-selfcheck', GO or NO-GO, what drifted, and each figure's change against the "
                            "registration with its trend per check, and each due check skipped (SKIPPED) "
                            "(--station: one station's)")
    chain.add_argument("--station", type=identity(), default=None, metavar="NAME",
                       help="a listing, --summary, --rig or --verify: only this station's; with --map-login: the "
                            "login's station")
    chain.add_argument("--schema", action="store_true",
                       help="the database's schema revision and the changes --upgrade would make")
    chain.add_argument("--upgrade", action="store_true",
                       help="apply this edc-bench's schema changes (the owner's login; a station's SQLite file is "
                            "upgraded when opened)")
    chain.add_argument("--setup-roles", action="store_true",
                       help="PostgreSQL: create the roles edc_station, edc_engineer, edc_owner and grant their "
                            "rights (the database owner's login)")


def chain_action(args: argparse.Namespace) -> Callable[[argparse.Namespace], int] | None:
    """The chain action the flags ask for (None: a listing, trend, export or --add), its flags checked."""
    from edc_bench.errors import ConfigError

    chosen = [name for name, flag in (("--withdraw", args.withdraw is not None), ("--audit", args.audit is not None),
                                      ("--verify", args.verify), ("--schema", args.schema),
                                      ("--upgrade", args.upgrade), ("--setup-roles", args.setup_roles),
                                      ("--add", bool(args.add)), ("--trend", args.trend is not None),
                                      ("--csv", args.csv is not None), ("--rig", args.rig),
                                      ("--map-login", args.map_login is not None),
                                      ("--heads", args.heads is not None and not args.verify)) if flag]
    if len(chosen) > 1:
        raise ConfigError(f"{' and '.join(chosen)} are separate actions: give one at a time")
    if args.station is not None and not (args.rig or args.verify or args.map_login is not None
                                         or args.summary or not chosen):
        raise ConfigError("--station goes with a listing or --summary (one station's tests), --rig, --verify (one "
                          "station's) or --map-login (the login's station)")
    if args.summary and chosen:
        raise ConfigError(f"--summary and {' and '.join(chosen)} are separate actions: give one at a time")
    if args.person is not None and args.map_login is None:
        raise ConfigError("--person goes with --map-login LOGIN (the person that database login is)")
    if args.shop is not None and not (args.map_login is not None or args.summary or not chosen):
        raise ConfigError("--shop goes with --map-login LOGIN --station NAME (the station's shop), --summary or a "
                          "listing (one shop's tests)")
    if args.verify and args.heads == "-":
        raise ConfigError("--verify --heads FILE: name the file of heads kept earlier ('edc-bench history --heads "
                          "> FILE' wrote it)")
    if args.withdraw is None and (args.why is not None or args.by is not None):
        raise ConfigError("--why and --by go with --withdraw TEST_ID")
    if args.withdraw is not None:
        from edc_bench.cli.common import text_problem

        extra = [flag for flag, value in (("--valve-id", args.valve_id), ("--pump-serial", args.pump_serial),
                                          ("--variant", args.variant), ("--verdict", args.verdict),
                                          ("--since", args.since), ("--until", args.until), ("--limit", args.limit),
                                          ("--json", args.json or None)) if value is not None]
        if extra:
            raise ConfigError(f"--withdraw TEST_ID withdraws one test (its id from the listing): {', '.join(extra)} "
                              "does not go with it")

        why = (args.why or "").strip()
        problem = "is missing" if not why else text_problem(why, MAX_WHY_CHARS)
        if problem:
            raise ConfigError(f"--why {problem}: say why the test is withdrawn (kept with it for good), e.g. "
                              "--why 'valve id typed wrong; retested as V-1043'")
        return _withdraw
    if args.rig:
        from edc_bench.cli.history_rig import run_rig

        return run_rig
    return {"--audit": _audit, "--verify": _verify, "--schema": _schema, "--upgrade": _upgrade,
            "--setup-roles": _setup_roles, "--map-login": _map_login, "--heads": _heads}.get(chosen[0] if chosen
                                                                                            else "")


def _withdraw(args: argparse.Namespace) -> int:
    from edc_bench.history.store import HistoryStore

    from edc_bench.cli.common import person_name

    by = person_name(args.by, "who withdraws the test")
    with HistoryStore(args.db, must_exist=True) as store:
        row = store.withdraw_test(args.withdraw, args.why.strip(), by)
    print(f"withdrew test {args.withdraw} (valve {row.valve_id}, {row.verdict}, tested "
          f"{local_text(row.started_at)}): it no longer counts; 'edc-bench history --audit "
          f"{row.valve_id}' shows it and why")
    return 0


def _audit(args: argparse.Namespace) -> int:
    from edc_bench.errors import ConfigError
    from edc_bench.history.store import HistoryStore

    with HistoryStore(args.db, must_exist=True) as store:
        events = store.audit(args.audit)
    if not events:
        raise ConfigError(f"the history holds nothing of valve {args.audit!r} (see 'edc-bench history')")
    if args.json:
        print_quietly_if_closed(lambda: print(json.dumps([dataclasses.asdict(e) for e in events], indent=2)))
    else:
        print_quietly_if_closed(lambda: _audit_table(events, args.audit))
    return 0


def _audit_table(events: list[AuditEvent], valve: str) -> None:
    from rich.console import Console
    from rich.table import Table
    from rich.text import Text

    written, zone = local_column([e.when for e in events], seconds=True)
    table = Table(title=Text(f"valve {valve}: {len(events)} entries, in the order written ({zone})"))
    for col in ("written", "what happened", "id", "details", "by", "database login", "chain"):
        table.add_column(col)
    for e, when in zip(events, written, strict=True):  # the technicians' text as typed: rich Text, never markup
        table.add_row(when, e.event, str(e.id), Text(e.what), Text(e.by), Text(e.db_login or ""),
                      (e.chain_hash or "")[:16])
    Console(width=None if sys.stdout.isatty() else 160).print(table)


def _verify(args: argparse.Namespace) -> int:
    from edc_bench.cli.exit_codes import ExitCode
    from edc_bench.history.day_counts import mismatches as day_count_mismatches
    from edc_bench.history.store import HistoryStore
    from edc_bench.history.verify import RecordFinding, changed_findings, model_findings, verify
    from edc_bench.verdict.classifier import shipped_model_hashes

    kept = _read_heads(args.heads) if args.heads is not None else None
    with HistoryStore(args.db, must_exist=True, warn=lambda _problem: None) as store:  # the breaks are listed below
        rows = store.indexed(args.station)
        changes = store.changed_tests(args.station)
        adoptions = store.adoptions()
        breaks = store.chain_breaks(args.station)
        misflagged = store.first_indexing_mismatches(args.station)
        with store.reading() as conn:
            misflagged += day_count_mismatches(conn)
        gone_heads = store.missing_heads(kept) if kept is not None else []
        restored = [f"the history's append-only triggers were found missing or changed and restored at "
                    f"{local_text(e.happened_at, seconds=True)} ({e.detail}): rows may have been changed "
                    "while they were (the chain above names where)" for e in store.guard_events()]
        where = store.shown_url
    found: list[RecordFinding] = verify(rows) + changed_findings(changes) + model_findings(rows, adoptions,
                                                                                    shipped_model_hashes())
    chain = [b.line() for b in breaks] + misflagged + gone_heads + restored
    if args.json:
        print(json.dumps({"checked": len(rows), "station": args.station, "findings": [f.__dict__ for f in found],
                          "chain": chain}, indent=2))
    else:
        for f in found:
            print(f"{f.problem}: test {f.test_id} (valve {f.valve_id}) {f.record_dir}: {f.detail}")
        for line in chain:
            print(f"chain: {line}")
        missing = sum(f.problem == "missing" for f in found)
        changed = sum(f.problem == "changed" for f in found)
        models = sum(f.problem == "model" for f in found)
        of = f" of station {args.station}" if args.station else ""
        print(f"checked {len(rows)} indexed record folder(s){of} in {where}: {missing} missing, "
              f"{len(found) - missing - changed - models} altered since indexed, {changed} indexed again with other "
              f"content, {models} judged by a model never adopted; the chain: "
              f"{'holds' if not chain else f'{len(chain)} problem(s)'}", file=sys.stderr)
    return ExitCode.HISTORY_NOT_AS_INDEXED if found or chain else ExitCode.OK


def _row_id(value: object) -> bool:
    """Whether ``value`` can be a row's id as ``--heads`` writes it (a number a database's id column holds)."""
    return isinstance(value, int) and not isinstance(value, bool) and 0 < value < 2**63


def _read_heads(path: str) -> list[ChainHead]:
    """The chain heads kept in ``path`` (``history --heads`` wrote them), checked."""
    from pathlib import Path

    from edc_bench.errors import ConfigError

    try:
        heads = json.loads(Path(path).read_text(encoding="utf-8"))
    except OSError as exc:
        raise ConfigError(f"--heads {path}: cannot read it ({exc.strerror})") from None
    except ValueError:
        raise ConfigError(f"--heads {path}: not the JSON 'edc-bench history --heads' writes") from None
    if not isinstance(heads, list) or not all(isinstance(h, dict) and {"table", "id", "row_hash"} <= set(h)
                                              and _row_id(h["id"]) for h in heads):
        raise ConfigError(f"--heads {path}: not the JSON 'edc-bench history --heads' writes (a list of table, id, "
                          "row_hash; each id a row's number)")
    return [ChainHead(str(h["table"]), str(h.get("chain") or ""), h["id"], str(h["row_hash"])) for h in heads]


def _heads(args: argparse.Namespace) -> int:
    from edc_bench.history.store import HistoryStore

    with HistoryStore(args.db, must_exist=True) as store:
        heads = store.heads()
    text = json.dumps([dataclasses.asdict(head) for head in heads], indent=2)
    if args.heads == "-":
        print_quietly_if_closed(lambda: print(text))
    else:
        from pathlib import Path

        from edc_bench.cli.common import check_output_file
        from edc_bench.paths import atomic_write

        check_output_file(Path(args.heads), "--heads")  # a folder, or one that cannot be written: one line
        atomic_write(Path(args.heads), lambda f: f.write(text + "\n"), mode="w")
        print(f"wrote {len(heads)} chain head(s) to {args.heads}: keep it away from the station; "
              f"'edc-bench history --verify --heads {args.heads}' checks them later", file=sys.stderr)
    return 0


def _map_login(args: argparse.Namespace) -> int:
    from edc_bench.errors import ConfigError
    from edc_bench.history.store import HistoryStore

    from edc_bench.cli.common import person_name

    with HistoryStore(args.db, must_exist=True) as store:
        if store.is_sqlite:
            raise ConfigError(f"--map-login is for a shop's PostgreSQL history; {store.shown_url} is a station's "
                              "SQLite file, which has no logins")
        if not args.map_login:
            if args.station is not None or args.person is not None:
                raise ConfigError("--map-login LOGIN --station NAME: name the database login to map")
            rows = store.logins()
            for r in rows:
                print(f"{r.login}: station {r.station or '(none)'}" + (f" of shop {r.shop}" if r.shop else "")
                      + f", person {r.person or '(the login)'} (mapped {local_text(r.mapped_at)} by {r.mapped_by})")
            if not rows:
                print("no login is mapped yet: edc-bench history --map-login LOGIN --station NAME")
            return 0
        if args.station is None and args.person is None:
            raise ConfigError(f"--map-login {args.map_login}: give --station NAME (a station's login) and/or --person "
                              "NAME (the person the login is)")
        if args.shop is not None and args.station is None:
            raise ConfigError(f"--map-login {args.map_login} --shop {args.shop}: a shop is a station's; give the "
                              "login's --station NAME too")
        row = store.map_login(args.map_login, args.station, args.person, person_name(None, "who maps the login"),
                              shop=args.shop)
    print(f"database login {row.login} is station {row.station or '(none)'}"
          + (f" of shop {args.shop}" if args.shop else "")
          + (f", person {row.person}" if row.person else "")
          + ": the database writes it into that login's rows from now on")
    return 0


def _schema_engine(args: argparse.Namespace) -> tuple[Any, str]:
    """An engine on the database without the store's revision check (the owner's actions work on any revision)."""
    import sqlalchemy as sa

    from edc_bench.history.secrets import shown_url
    from edc_bench.history.url import check_url, default_url

    check_url(args.db, must_exist=True)  # a mistyped file is not created by looking at it
    url = args.db or default_url()
    return sa.create_engine(url, hide_parameters=True), shown_url(url)


def _schema(args: argparse.Namespace) -> int:
    from edc_bench.history import migrate

    engine, where = _schema_engine(args)
    with _owner_errors("read", where, engine), engine.connect() as conn:
        revision = migrate.current(conn)
    steps = migrate.pending(revision)
    print(f"history database {where}: schema revision {revision or '(none)'}; this edc-bench's: {migrate.head()}")
    for step in steps:
        print(f"  to apply: {step.id}  {step.summary}")
    if not steps:
        print("  nothing to apply")
    return 0


def _upgrade(args: argparse.Namespace) -> int:
    from edc_bench.history import migrate

    engine, where = _schema_engine(args)
    with _owner_errors("upgrade", where, engine):
        done = migrate.upgrade(engine)
    for step in done:
        print(f"applied {step.id}  {step.summary}")
    print(f"history database {where} is at schema revision {migrate.head()}"
          + ("" if done else " (nothing to apply)"))
    return 0


def _setup_roles(args: argparse.Namespace) -> int:
    from edc_bench.errors import ConfigError
    from edc_bench.history import migrate
    from edc_bench.history.roles import ENGINEER, OWNER, STATION, setup_roles

    engine, where = _schema_engine(args)
    if engine.dialect.name != "postgresql":
        raise ConfigError(f"--setup-roles is for a shop's PostgreSQL history; {where} is a station's SQLite file, "
                          "whose file permissions say who may write it")
    with _owner_errors("setup-roles", where, engine), engine.begin() as conn:
        migrate.require_head(conn, where)
        created = setup_roles(conn)
    print(f"roles in {where}: {STATION} (add tests, read), {ENGINEER} (also findings, withdrawals, adoptions), "
          f"{OWNER} (owns the tables: schema changes)" + (f"; created {', '.join(created)}" if created else
                                                          "; all there already, rights granted again"))
    print(f"give each login one: CREATE ROLE bench3 LOGIN IN ROLE {STATION}; (docs/shop-network.md)")
    return 0


def _owner_errors(action: str, where: str, engine: Any) -> AbstractContextManager[None]:
    from edc_bench.history.guard import database_errors
    from edc_bench.history.secrets import known_secrets

    return database_errors(action, where, known_secrets(engine.url.render_as_string(hide_password=False)),
                           engine.url.username)


__all__ = ["add_chain_arguments", "chain_action"]
