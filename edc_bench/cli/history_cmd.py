"""``edc-bench history``: list and filter the station's tests, one valve's trend, CSV export; and the chain's
side (:mod:`edc_bench.cli.history_chain`): withdrawals, the audit trail, ``--verify``, the schema and roles."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from edc_bench.cli.common import (
    add_hidden_alias,
    add_history_db_argument,
    add_include_simulated_argument,
    given_path,
    given_path_text,
    identity,
    positive_int,
    print_quietly_if_closed,
)
from edc_bench.history.rows import TestRow
from edc_bench.history.visits import visits, with_visit_decisions
from edc_bench.timefmt import local_column, utc_bound
from edc_bench.verdict.verdicts import Verdict


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Register the command."""
    p = sub.add_parser(
        "history", help="list past tests, a valve's trend, CSV export",
        description="The station's history: every test 'edc-bench test' ran is indexed (SQLite in the data "
                    "folder, or the PostgreSQL database EDC_BENCH_HISTORY_URL or --db names). Filters combine. "
                    "--trend shows one valve's af and a1 over its visits against the new-valve baseline.",
    )
    add_history_db_argument(p)
    p.add_argument("--valve-id", type=identity(), default=None, metavar="ID", help="only this valve")
    add_hidden_alias(p, "--valve", "valve_id", type=identity())  # its name before --valve-id everywhere
    p.add_argument("--pump-serial", type=identity(), default=None, metavar="SERIAL", help="only this pump")
    p.add_argument("--variant", default=None, help="only this variant (name or part number)")
    p.add_argument("--verdict", default=None, type=str.upper,
                   choices=[v.value for v in Verdict], help="only this verdict")
    p.add_argument("--since", default=None, metavar="DATE",
                   help="from this day (YYYY-MM-DD, this PC's local day; or YYYY-MM-DDTHH:MM) on")
    p.add_argument("--until", default=None, metavar="DATE",
                   help="up to this day (YYYY-MM-DD, local), inclusive; or up to YYYY-MM-DDTHH:MM")
    p.add_argument("--limit", type=positive_int, default=None, metavar="N", help="only the newest N")
    p.add_argument("--trend", type=identity(), default=None, metavar="VALVE_ID",
                   help="one valve's af and a1 over its visits")
    add_include_simulated_argument(p, "with --trend or --summary: show")
    p.add_argument("--plot", type=given_path, default=None, metavar="PNG", help="with --trend: also draw it (a .png file)")
    p.add_argument("--csv", default=None, type=given_path_text, metavar="FILE",
                   help="write the listed tests as CSV ('-': stdout)")
    p.add_argument("--add", nargs="+", type=given_path, default=None, metavar="RECORD_DIR",
                   help="index record folders (after a test ran with --no-history, or to rebuild the history): "
                        "each good one is indexed, each bad one listed (exit 2)")
    p.add_argument("--json", action="store_true", help="print only JSON")
    from edc_bench.cli.history_chain import add_chain_arguments
    from edc_bench.cli.history_summary import add_summary_arguments

    add_summary_arguments(p)

    add_chain_arguments(p)
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    """List, trend, export or add (or one of the chain's actions)."""
    from edc_bench.cli.common import check_output_file
    from edc_bench.cli.exit_codes import ExitCode
    from edc_bench.cli.history_chain import chain_action
    from edc_bench.errors import ConfigError
    from edc_bench.history.store import Filters, HistoryStore, parse_day

    action = chain_action(args)
    if action is not None:
        return action(args)

    if args.plot is not None and args.trend is None:
        raise ConfigError("--plot draws a valve's trend: give --trend VALVE_ID too")
    if args.plot is not None:
        check_output_file(args.plot, "--plot", ".png")
    if args.csv is not None and args.csv != "-":
        check_output_file(Path(args.csv), "--csv")
    since, until = parse_day(args.since, "--since"), parse_day(args.until, "--until")
    # typed in local time, as the listing shows the tests: the UTC instants the stored stamps are compared with
    since = utc_bound(since) if since is not None else None
    until = utc_bound(until, end_of_day=True) if until is not None else None
    if since is not None and until is not None and since > until:
        raise ConfigError(f"--since {args.since} is after --until {args.until}: give the earlier day first")
    records: list[tuple[Any, Path]] = []
    bad: list[str] = []
    if args.add:  # each folder read and checked on its own: the good ones are indexed, each bad one is listed
        folders = list(dict.fromkeys(Path(folder).resolve() for folder in args.add))  # each folder once
        records, bad = _readable_records(folders)
        if not records:  # nothing to index: the history is not opened (nor made)
            for line in bad:
                print(f"edc-bench history: error: {line}", file=sys.stderr)
            return ExitCode.BAD_INPUT
    with HistoryStore(args.db, must_exist=not args.add) as store:
        if args.add:
            outcomes = [store.add(record, folder) for record, folder in records]
            new, changed = outcomes.count("new"), outcomes.count("changed")
            same, withdrawn = outcomes.count("unchanged"), outcomes.count("withdrawn")
            print(f"indexed {new} new record folder(s) in {store.shown_url}"
                  + (f"; {changed} indexed before with other content: each recorded as a change (the first "
                     "indexing stands; 'history --verify' and '--audit' show it)" if changed else "")
                  + (f"; {same} already indexed as they are" if same else "")
                  + (f"; {withdrawn} withdrawn before, and not indexed again (see 'history --audit')" if withdrawn
                     else "")
                  + (f" ({len(args.add) - len(folders)} given more than once)" if len(args.add) > len(folders)
                     else "")
                  + (f"; {len(bad)} not indexed (below)" if bad else ""), file=sys.stderr)
            for line in bad:
                print(f"edc-bench history: not indexed: {line}", file=sys.stderr)
            return ExitCode.BAD_INPUT if bad else ExitCode.OK
        if args.trend is not None:
            return _trend(store, args)
        filters = Filters(valve_id=args.valve_id, pump_serial=args.pump_serial, variant=args.variant,
                          verdict=args.verdict, since=since, until=until, station=args.station,
                          operator=args.operator, shop=args.shop)
        if args.summary:  # as the web view's chain page: a rig's tests, the simulated rig's only if asked for
            from dataclasses import replace

            from edc_bench.cli.history_summary import print_summary
            from edc_bench.history.summary import chain_summary

            print_summary(chain_summary(store, replace(filters, simulated=None if args.include_simulated else False)),
                          args.json)
            return 0
        rows = store.list(filters, args.limit)
    if args.csv is not None:
        _export(rows, args.csv)
        return 0
    if args.json:  # a row per test, each with its visit's decision
        print_quietly_if_closed(lambda: print(json.dumps(with_visit_decisions(rows), indent=2)))
    else:
        print_quietly_if_closed(lambda: history_table(rows, store.shown_url))
    return 0


def _readable_records(folders: list[Path]) -> tuple[list[tuple[Any, Path]], list[str]]:
    """The records of ``folders`` that may be indexed, and one line for each that may not (unreadable, changed
    since its test, or a verdict that does not follow from its own figures)."""
    from edc_bench.errors import EdcBenchError
    from edc_bench.records.consistency import disagreements, refusal
    from edc_bench.records.reader import load_record

    records, bad = [], []
    for folder in folders:
        try:
            record = load_record(folder)
        except (EdcBenchError, OSError) as exc:
            bad.append(str(exc) if isinstance(exc, EdcBenchError) else f"{folder}: {exc}")
            continue
        found = disagreements(record)
        if found:
            bad.append(refusal(folder, record, found, "not indexed"))
            continue
        records.append((record, folder))
    return records, bad


def _export(rows: list[TestRow], target: str) -> None:
    from edc_bench.history.rows import LIST_COLUMNS
    from edc_bench.history.store import write_csv

    if target == "-":
        print_quietly_if_closed(lambda: write_csv(rows, sys.stdout, LIST_COLUMNS))
        return
    from edc_bench.paths import atomic_write

    path = Path(target)  # checked before the history was read (run)
    atomic_write(path, lambda f: write_csv(rows, f, LIST_COLUMNS), mode="w")
    print(f"wrote {len(rows)} test(s) to {path}", file=sys.stderr)


def _fmt(value: Any, spec: str) -> str:
    return "" if value is None else format(value, spec)


def history_table(rows: list[TestRow], url: str, console: Any = None) -> None:
    """Print the listed tests, a line per visit: a retested MARGINAL's two tests on one line with their decision."""
    from rich.console import Console
    from rich.table import Table
    from rich.text import Text

    from edc_bench.ui.live import VERDICT_STYLES

    # ids and names are the technicians' text, kept as given: rich Text, never read as markup ("V[/1]" is an id)
    shown = visits(rows)
    simulated = sum(bool(r.simulated) for r in rows)
    changed = sum(bool(r.changes) for r in rows)
    started, zone = local_column([v.first.started_at for v in shown])
    table = Table(title=Text(f"{len(shown)} visit(s), {len(rows)} test(s) in {url} ({zone})"
                             + (f"; sim: {simulated} on the simulated rig, out of trends and training" if simulated
                                else "")
                             + (f"; {changed} CHANGED: indexed again with other content after their first indexing, "
                                "which stands (history --verify, --audit)" if changed else "")))
    # the figures (af and a1, P(faulty), the distance) are the engineer's: in --trend, --json and --csv; here the
    # visits and what was decided. Ids wrap (folded), never cut: a person reads the whole id. A terminal under
    # 100 columns gets the visit, its tests and decision only (the rest in --json), rather than a table cut short
    console = console or Console(width=None if sys.stdout.isatty() else 160)
    wide = console.width >= 100
    if not wide:
        table.caption = "pump type, station and operator: in a wider terminal, or with --json"
    table.add_column("id", no_wrap=True)
    table.add_column("started", no_wrap=True)
    for col in ("valve", "pump serial", *(("variant",) if wide else ())):
        table.add_column(col, overflow="fold", min_width=6)
    if wide:
        table.add_column("sim", no_wrap=True)
    table.add_column("tests", min_width=9)
    table.add_column("decision", no_wrap=True)
    if wide:
        for col in ("station", "operator"):
            table.add_column(col, overflow="fold", min_width=7)
    for visit, when in zip(shown, started, strict=True):
        r = visit.last  # the test that decided
        changes = sum(int(t.changes or 0) for t in visit.tests)
        tests_text = (Text(visit.verdicts) + Text(" (sim)" if r.simulated and not wide else "", style="dim")
                      + Text(f" CHANGED {changes}x" if changes else "", style="bold red"))
        cells = [visit.ids, when, Text(r.valve_id), Text(r.pump_serial)]
        if wide:
            cells += [Text(r.variant), "yes" if r.simulated else ""]
        cells += [tests_text, Text(visit.decision, style=VERDICT_STYLES.get(visit.decision, ""))]
        if wide:
            cells += [Text(r.station), Text(r.operator)]
        table.add_row(*cells)
    console.print(table)


def _trend(store: Any, args: argparse.Namespace) -> int:
    rows = store.trend(args.trend, args.include_simulated)
    if not rows:
        from edc_bench.errors import ConfigError

        simulated = store.trend(args.trend, include_simulated=True) if not args.include_simulated else []
        raise ConfigError(f"no trustworthy test of valve {args.trend!r} on a rig in the history (see 'edc-bench "
                          "history')" + (f"; {len(simulated)} on the simulated rig: add --include-simulated to see "
                                         "them" if simulated else ""))
    if args.plot is not None:
        _plot(visits(rows), args.trend, args.plot)
    if args.json:  # a row per test, each with its visit's decision
        print_quietly_if_closed(lambda: print(json.dumps(with_visit_decisions(rows), indent=2)))
        return 0

    print_quietly_if_closed(lambda: trend_table(rows, args.trend))
    return 0


def trend_table(rows: list[TestRow], valve: str, console: Any = None) -> None:
    """Print one valve's visits with the change against the baseline: a retested MARGINAL is one visit, its
    retest's figures and the pair's decision."""
    from rich.console import Console
    from rich.table import Table
    from rich.text import Text

    shown = visits(rows)
    started, zone = local_column([v.first.started_at for v in shown])
    table = Table(title=Text(f"valve {valve}: {len(shown)} visit(s); change against the new-valve baseline ({zone})"))
    for col in ("started", "variant", "tests", "decision", "af V", "af change", "a1 V s/mm", "a1 change",
                "distance"):
        table.add_column(col)
    for visit, when in zip(shown, started, strict=True):
        r = visit.last
        table.add_row(when, Text(r.variant), Text(visit.verdicts), Text(visit.decision), _fmt(r.af_v, ".5f"),
                      _pct(r.af_rel), _fmt(r.a1_v_s_per_mm, ".6f"), _pct(r.a1_rel), _fmt(r.distance, "+.3f"))
    (console or Console(width=None if sys.stdout.isatty() else 160)).print(table)


def _pct(rel: float | None) -> str:
    return "" if rel is None else f"{rel - 1:+.1%}"


def _plot(shown: list[Any], valve: str, path: Path) -> None:
    """Draw one valve's trend (:func:`edc_bench.history.trend_plot.trend_figure`) to a PNG file."""
    from edc_bench.history.trend_plot import close, trend_figure
    from edc_bench.paths import atomic_write

    fig = trend_figure(shown, valve)
    atomic_write(path, lambda f: fig.savefig(f, format="png", dpi=120))
    close(fig)
