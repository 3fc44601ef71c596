"""``edc-bench label``: record what a valve's teardown found, the label the classifier can learn from."""

from __future__ import annotations

import argparse
import json
import math
import sys
from typing import TYPE_CHECKING

from edc_bench.cli.common import (
    MAX_ID_CHARS,
    add_hidden_alias,
    add_history_db_argument,
    person_name,
    positive_int,
    print_quietly_if_closed,
)
from edc_bench.timefmt import local_column, local_text, parse_local_input

if TYPE_CHECKING:
    from edc_bench.history.rows import TeardownMatch
    from edc_bench.history.store import HistoryStore

#: A plunger clearance beyond this (mm) is a typing error, not a measurement.
MAX_CLEARANCE_MM = 2.0

#: The longest note kept with a finding.
MAX_NOTE_CHARS = 2000


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Register the command."""
    p = sub.add_parser(
        "label", help="record a valve's teardown finding (reusable, worn or faulty) in the history",
        description="When a valve is opened, record what was found: reusable, worn or faulty, the clearance "
                    "measured, a note, who and when. The finding labels the valve's last judged test before the "
                    "teardown; 'edc-bench train --from-history' learns from the labelled tests (worn and faulty "
                    "both mean: replace). --list shows the findings and the tests they label.",
    )
    p.add_argument("valve_id", nargs="?", default=None, metavar="VALVE_ID", help="the valve, as its tests name it")
    p.add_argument("--finding", choices=("reusable", "worn", "faulty"), default=None, help="what the teardown found")
    p.add_argument("--clearance-mm", type=float, default=None, metavar="MM", help="plunger clearance measured (mm)")
    p.add_argument("--note", default="", help="anything else found")
    p.add_argument("--by", default=None, metavar="NAME", help="who opened the valve (default: the login name)")
    p.add_argument("--date", default=None, metavar="DATE",
                   help="when the valve was opened: YYYY-MM-DD (the whole day: a test that day counts) or "
                        "YYYY-MM-DDTHH:MM (this PC's local time unless an offset is given) (default: now)")
    add_history_db_argument(p)
    p.add_argument("--new-valve", action="store_true",
                   help="record the finding although the history has no test of this valve (tested elsewhere, or "
                        "its test to be added later with 'edc-bench history --add')")
    p.add_argument("--list", action="store_true", help="list the findings (of VALVE_ID if given)")
    p.add_argument("--corrects", type=positive_int, default=None, metavar="ID",
                   help="with --finding: this finding replaces finding ID of the same valve (recorded by mistake); "
                        "both stay in 'edc-bench history --audit'")
    p.add_argument("--withdraw", type=positive_int, default=None, metavar="ID",
                   help="withdraw finding ID (from --list) with --why: it labels nothing any more; nothing is deleted")
    # what withdrawing was called before (the finding was removed then): withdrawn 'recorded by mistake'
    add_hidden_alias(p, "--delete", "delete", type=positive_int)
    p.add_argument("--why", default=None, metavar="TEXT", help="with --withdraw: why (kept in the audit trail)")
    p.add_argument("--json", action="store_true", help="print JSON")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    """Record or list."""
    from edc_bench.cli.common import text_problem
    from edc_bench.errors import ConfigError
    from edc_bench.history.store import Filters, HistoryStore

    delete = getattr(args, "delete", None)
    if args.withdraw is not None or delete is not None:
        return _withdraw(args, delete)
    if args.why is not None:
        raise ConfigError("--why goes with --withdraw ID")
    if args.corrects is not None and args.finding is None:
        raise ConfigError("--corrects ID goes with the finding that replaces it: edc-bench label VALVE_ID --finding "
                          "reusable|worn|faulty --corrects ID")
    if args.list:
        if args.finding is not None:
            raise ConfigError("--list shows findings; record one without --list")
        with HistoryStore(args.db, must_exist=True) as store:
            rows = _listing(store, args.valve_id)
        print_quietly_if_closed(lambda: _print_list(rows, args.json))
        return 0
    if args.valve_id is None or args.finding is None:
        raise ConfigError("give the valve and what its teardown found: edc-bench label VALVE_ID --finding "
                          "reusable|worn|faulty [--clearance-mm MM] [--note TEXT] (or --list)")
    valve_id = args.valve_id  # as the tests recorded it, spaces and all
    problem = "is empty" if not valve_id.strip() else text_problem(valve_id, MAX_ID_CHARS)
    if problem:
        raise ConfigError(f"VALVE_ID {args.valve_id!r} {problem}; give the id the valve's tests were recorded with "
                          "(--valve-id of 'edc-bench test', see 'edc-bench history')")
    problem = text_problem(args.note, MAX_NOTE_CHARS, lines=True)
    if problem:
        raise ConfigError(f"--note {problem}")
    clearance = args.clearance_mm
    if clearance is not None and not (math.isfinite(clearance) and 0 < clearance <= MAX_CLEARANCE_MM):
        raise ConfigError(f"--clearance-mm {clearance}: a plunger clearance is above 0 and at most "
                          f"{MAX_CLEARANCE_MM} mm (e.g. 0.19)")
    when = _teardown_time(args.date)
    by = person_name(args.by, "who opened the valve")
    with HistoryStore(args.db, must_exist=True) as store:
        if not args.new_valve and not store.list(Filters(valve_id=valve_id), 1):
            raise ConfigError(f"no test of valve {valve_id!r} in {store.shown_url}: check the id ('edc-bench history' "
                              "lists the tests), or give --new-valve to record the finding all the same")
        store.add_teardown(valve_id, args.finding, labelled_by=by, labelled_at=when, clearance_mm=clearance,
                           note=args.note, corrects=args.corrects)
        match = next(m for m in reversed(_listing(store, valve_id)) if m.teardown.labelled_at == when)
    test = match.test
    if args.json:
        print(json.dumps(match.listed(), indent=2))
    elif test is not None:
        print(f"valve {valve_id}: {args.finding} recorded; it labels the test of {local_text(test.started_at)} "
              f"({test.verdict}, {test.record_dir})"
              + ("; that test ran on the simulated rig: training leaves it out unless --include-simulated"
                 if test.simulated else ""))
    else:
        print(f"valve {valve_id}: {args.finding} recorded", file=sys.stderr)
        print(f"note: no judged test of valve {valve_id!r} before {when} in {store.shown_url}; the finding labels nothing "
              "until one is there (a test added later with 'edc-bench history --add' counts if it ran before the "
              "teardown)", file=sys.stderr)
    return 0


def _withdraw(args: argparse.Namespace, delete: int | None) -> int:
    """Withdraw one finding, saying why (``--delete ID``, its old spelling: 'recorded by mistake')."""
    from edc_bench.cli.common import text_problem
    from edc_bench.errors import ConfigError
    from edc_bench.history.store import HistoryStore

    given = [flag for flag, value in (("VALVE_ID", args.valve_id), ("--finding", args.finding),
                                      ("--clearance-mm", args.clearance_mm), ("--note", args.note or None),
                                      ("--date", args.date), ("--corrects", args.corrects),
                                      ("--list", args.list or None), ("--new-valve", args.new_valve or None))
             if value is not None]
    if given or (args.withdraw is not None and delete is not None):
        raise ConfigError(f"--withdraw ID withdraws one finding, with --why (and --by): "
                          f"{', '.join(given) or '--delete'} does not go with it; record the right finding in a second "
                          "command, or in one with --finding ... --corrects ID")
    why = (args.why or ("recorded by mistake" if delete is not None else "")).strip()
    problem = "is missing" if not why else text_problem(why, MAX_NOTE_CHARS)
    if problem:
        raise ConfigError(f"--why {problem}: say why the finding is withdrawn (kept with it for good), e.g. "
                          "--why 'typed worn for reusable'")
    by = person_name(args.by, "who withdraws it")
    with HistoryStore(args.db, must_exist=True) as store:
        gone = store.withdraw_teardown(args.withdraw if args.withdraw is not None else delete, why, by)
    print(f"withdrew finding {gone.id}: valve {gone.valve_id}, {gone.finding}, {local_text(gone.labelled_at)} "
          f"({why}); it labels nothing now")
    return 0


def _teardown_time(text: str | None) -> str:
    """The teardown's time as stored: a date alone as given, a date-time in UTC (typed in local time unless it
    gives an offset); never in the future."""
    import datetime as dt

    from edc_bench.errors import ConfigError

    now = dt.datetime.now(dt.UTC)
    if text is None:
        return now.isoformat(timespec="seconds")
    hint = "write it as YYYY-MM-DD or YYYY-MM-DDTHH:MM (local time, or with an offset such as +02:00)"
    try:
        if "T" in text:
            moment = parse_local_input(text).astimezone(dt.UTC)
            value, later = moment.isoformat(timespec="seconds"), moment > now
        else:
            day = dt.date.fromisoformat(text)
            value, later = day.isoformat(), day > now.date()
    except ValueError:
        raise ConfigError(f"--date {text!r} is not a date: {hint}") from None
    if later:
        raise ConfigError(f"--date {text}: that is in the future; give the day the valve was opened")
    return value


def _listing(store: HistoryStore, valve_id: str | None) -> list[TeardownMatch]:
    """The findings and the tests they label, on the simulated rig too (training leaves those out unless asked)."""
    return [m for m in store.teardown_matches(include_simulated=True)
            if valve_id is None or m.teardown.valve_id == valve_id]


def _print_list(matches: list[TeardownMatch], as_json: bool) -> None:
    if as_json:
        print(json.dumps([m.listed() for m in matches], indent=2))
        return
    from rich.console import Console
    from rich.table import Table
    from rich.text import Text

    opened, zone = local_column([m.teardown.labelled_at for m in matches])
    tested, _ = local_column([m.test.started_at if m.test is not None else None for m in matches])
    table = Table(title=f"{len(matches)} teardown finding(s) ({zone})")
    for col in ("id", "opened", "valve", "finding", "clearance mm", "by", "labels the test of", "verdict then",
                "af/af0", "a1/a1_0"):
        table.add_column(col)
    for m, opened_at, tested_at in zip(matches, opened, tested, strict=True):
        f, test = m.teardown, m.test
        # ids and names as the technicians typed them: rich Text, never read as markup
        table.add_row(str(f.id), opened_at, Text(f.valve_id), f.finding,
                      "" if f.clearance_mm is None else f"{f.clearance_mm:.3f}", Text(f.labelled_by),
                      tested_at or "(no judged test)", test.verdict if test is not None else "",
                      "" if test is None or test.af_rel is None else f"{test.af_rel:.3f}",
                      "" if test is None or test.a1_rel is None else f"{test.a1_rel:.3f}")
    Console(width=None if sys.stdout.isatty() else 160).print(table)
