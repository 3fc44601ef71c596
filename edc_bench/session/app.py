"""The session's screen (Textual): operator, prompts, the live test, the verdict with what to do, the shift summary.

The screen only shows and asks; :mod:`.scan` says what a line means, :mod:`.runner` runs the tests and keeps
their records, :mod:`.shift` counts the shift. A test runs in a worker thread and the screen reads its figures
four times a second from a :class:`~edc_bench.ui.snapshot.Snapshot`; the verdict stays on screen until the next
valve id is scanned.
"""

from __future__ import annotations

import shutil
import subprocess
import threading
import time
from dataclasses import replace
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from rich.text import Text
from textual import events, work
from textual.app import App, ComposeResult, ScreenStackError
from textual.binding import Binding
from textual.containers import Horizontal, Vertical
from textual.screen import ModalScreen
from textual.css.query import NoMatches
from textual.widgets import Footer, Input, Label, Static

from edc_bench.runtime.priority import priority_notice
from edc_bench.runtime.signals import stop_requested
from edc_bench.session.rig_selfcheck import SelfCheckWords, SessionSelfCheck
from edc_bench.session.runner import SessionRunner, ValveDone
from edc_bench.session.scan import PROMPTS, Scan, ScanContext, Step, read_line
from edc_bench.session.scan_rules import ScanRules
from edc_bench.session.shift import RigCheckEntry, ShiftLog, ValveEntry, now_local
from edc_bench.ui.snapshot import Snapshot

#: Colours of each verdict's block (white text on them).
#: A second Ctrl+Q within this many seconds of the first ends the shift.
END_CONFIRM_S = 10.0
#: why a rig self-check is asked for when the technician pressed F6 (not due: a skip of it is not kept)
ASKED_FOR = "asked for"
VERDICT_COLOURS = {"PASS": "green", "MARGINAL": "#b58900", "FAIL": "red", "INVALID": "magenta"}


class SnapshotObserver:
    """A :class:`~edc_bench.runtime.loop.LoopObserver` that copies the running test into a snapshot the screen
    reads (a lock keeps the screen from reading half a tick)."""

    def __init__(self) -> None:
        self.snapshot = Snapshot()
        self.lock = threading.Lock()
        #: time.monotonic() when the test's loop had stopped the rig safely (its judgement begins), None before
        self.safe_stopped_at: float | None = None

    def phase(self, name: str) -> None:
        """A new phase began."""
        if name == "classify":
            self.safe_stopped_at = time.monotonic()
        with self.lock:
            self.snapshot.enter(name)

    def tick(self, k: int, loop: Any) -> None:
        """Copy tick ``k``'s figures."""
        from edc_bench.ui.snapshot import read_tick

        figures = read_tick(k, loop)
        with self.lock:
            self.snapshot.apply(figures)


class OperatorScreen(ModalScreen[str]):
    """Asks the operator's name (once per station; F2 changes it)."""

    def __init__(self, current: str) -> None:
        super().__init__()
        self.current = current

    def compose(self) -> ComposeResult:
        with Vertical(id="operator-box"):
            yield Label("Who is working at this bench? Type your NAME, then Enter")
            yield Input(value=self.current, placeholder="your name", id="operator-name")
            yield Label("", id="operator-message")

    def on_input_submitted(self, event: Input.Submitted) -> None:
        name = event.value.strip()
        if not name or len(name) > 100 or not name.isprintable():
            self.query_one("#operator-message", Label).update("a name of 1 to 100 printable characters, please")
            return
        self.dismiss(name)


class ScanInput(Input):
    """The scan entry: Enter takes the line and empties the entry at once, in the order the keys came.

    Textual's Input inserts a character as its key arrives, but an Enter goes up to the app's bindings and comes
    back as a submit later: a scanner's next line, sent right after (a valve label, then the pump's), was typed
    onto the first meanwhile. In tmux "V-2043" Enter "PS-8" Enter came out as the valve id "V-2043PS-8", or as
    "V-2043PS" and "-8". Here the Enter is taken where the characters are, and the entry emptied with it: every
    line is one scan.
    """

    async def _on_key(self, event: events.Key) -> None:
        if event.key == "enter":
            event.stop()
            event.prevent_default()
            line = self.value
            self.post_message(self.Submitted(self, line))  # before the emptying's Changed, which must not overtake it
            self.value = ""
            return
        await super()._on_key(event)


class WorkshopScreen(ModalScreen[tuple[str, ...] | None]):
    """Asks the workshop's name and address once per station, for the customer's page of every report (kept in the
    station's settings, ``[station] shop`` and ``shop_address``; Enter alone in both: none is printed), and where the
    settings name no station, the bench's name that page prints (``[station] shown_name``; the PC's host name never
    is). One entry,
    one line at a time, as the scans are taken: a line typed at once after the name's Enter is the address whole."""

    ASKED = ("The customer's reports name your workshop. Type the WORKSHOP's NAME, then Enter (Enter alone: none)",
             "Now its ADDRESS on one line, then Enter (Enter alone: none)",
             "And this BENCH's NAME as the reports print it, e.g. Bench 2, then Enter (Enter alone: none)")
    LONGEST = (100, 300, 100)
    PLACEHOLDERS = ("workshop name", "street, town", "bench name")

    def __init__(self, ask_station: bool = False) -> None:
        super().__init__()
        self.answers: list[str] = []
        self.asked = 3 if ask_station else 2  # the bench's name only where the station's settings give none

    def compose(self) -> ComposeResult:
        with Vertical(id="operator-box"):
            yield Label(self.ASKED[0], id="workshop-asked")
            yield ScanInput(placeholder="workshop name", id="workshop-line")
            yield Label("", id="workshop-message")

    def on_input_submitted(self, event: Input.Submitted) -> None:
        event.stop()  # the scan entry's handler is the app's: not this line's
        if len(self.answers) >= self.asked:  # an Enter queued behind the last answer: the screen is closing
            return
        value = event.value.strip()
        longest = self.LONGEST[len(self.answers)]
        if len(value) > longest or not value.isprintable():
            self.query_one("#workshop-message", Label).update(f"at most {longest} printable characters, please: "
                                                              "type it again")
            return
        self.answers.append(value)
        self.query_one("#workshop-message", Label).update("")
        if len(self.answers) == self.asked:
            self.dismiss(tuple(self.answers))
            return
        self.query_one("#workshop-asked", Label).update(self.ASKED[len(self.answers)])
        self.query_one("#workshop-line", Input).placeholder = self.PLACEHOLDERS[len(self.answers)]


class SessionApp(App[None]):
    """A shift at the bench.

    Parameters
    ----------
    runner : SessionRunner
        Runs the tests and keeps their records.
    variant_loader : callable
        Variant name -> :class:`~edc_bench.config.models.Variant`.
    variant_name : str
        The session's pump type until a part number is scanned.
    part_numbers : Mapping[str, str]
        Part number -> variant name, of the variant library.
    operator : str
        The operator remembered for this station ("" asks).
    remember_operator : callable
        Keeps a newly named operator for the next session.
    history_of : callable
        Valve id -> its earlier tests (newest first), lines for the screen.
    selfcheck : SessionSelfCheck, optional
        The station's rig self-check: run at the start of the shift and whenever it is due (None: none).
    shift_folder : pathlib.Path
        Where the shift summary is written.
    remember_workshop : callable, optional
        Keeps the workshop's name and address in the station's settings: given where they are not set yet, and the
        session asks for them once, after the operator (None: not asked).
    ask_station_name : bool
        With the workshop, ask the bench's name the customer's page prints (the settings name no station for
        customers, and no --station was given): kept by ``remember_workshop(..., shown_name=NAME)``.
    """

    TITLE = "edc-bench session"
    ENABLE_COMMAND_PALETTE = False  # its Quit would end the shift without its summary or the report being drawn
    CSS = """
    Screen { layout: vertical; }
    #status { height: auto; background: $boost; padding: 0 1; }
    #prompt { width: 1fr; height: auto; margin: 1 1 0 1; text-style: bold; }
    #entry { margin: 0 1; }
    #message { height: auto; margin: 0 1; color: $warning; }
    #verdict { display: none; height: 5; content-align: center middle; text-style: bold; margin: 1 1 0 1; }
    #words { height: auto; margin: 0 1; text-style: bold; }
    #body { height: 1fr; }
    #live { width: 2fr; }
    #side { width: 1fr; padding: 0 1; border-left: solid $panel; }
    #operator-box { width: 70; height: auto; border: thick $accent; padding: 1 2; background: $surface; }
    #operator-box Label { width: 1fr; }
    OperatorScreen, WorkshopScreen { align: center middle; }
    """
    BINDINGS = [
        Binding("f2", "change_operator", "Operator"),
        # short labels: the footer holds them all at 80 columns (the longer ones were cut at "esc Back to valv")
        Binding("f5", "print_report", "Print"),
        Binding("f6", "rig_selfcheck", "Self-check"),
        Binding("escape", "back", "Back"),
        Binding("ctrl+q", "end_shift", "End shift", priority=True),
    ]

    def __init__(self, runner: SessionRunner, variant_loader: Callable[[str | None], Any], variant_name: str | None,
                 part_numbers: Mapping[str, str], operator: str, remember_operator: Callable[[str], None],
                 history_of: Callable[[str], list[str]], shift_folder: Path,
                 selfcheck: SessionSelfCheck | None = None, scan_rules: ScanRules | None = None,
                 remember_workshop: Callable[..., Any] | None = None, ask_station_name: bool = False) -> None:
        super().__init__()
        self.remember_workshop = remember_workshop
        self.ask_station_name = ask_station_name
        self.scan_rules = scan_rules or ScanRules()
        self.runner, self.variant_loader, self.part_numbers = runner, variant_loader, part_numbers
        self.remember, self.history_of, self.shift_folder = remember_operator, history_of, shift_folder
        self.selfcheck = selfcheck
        self.awaiting_reference = ""  # the reference valve's id while the session waits for it to be mounted
        self.awaiting_why = ""  # and why it is asked for
        self.awaiting_due = False  # it is due (the policy, a NO-GO, the shift's start): a skip of it is kept
        self.variant = variant_loader(variant_name)
        self.scan = Scan(variant=self.variant.name)
        self.shift = ShiftLog(operator=operator, station=runner.station, rig=runner.rig.describe())
        self.observer: SnapshotObserver | None = None
        self.testing = False
        self.last: ValveDone | None = None
        self.summary_file: Path | None = None
        self.drawing = threading.Event()  # set while the last valve's reports are drawn
        self.end_when_drawn = False  # Ctrl+Q (or an interrupt) came while they were
        self.end_asked_at: float | None = None  # time.monotonic() of a first Ctrl+Q, which asks
        self.verdict_shown = False  # the last valve's verdict is on screen (until the next valve id)
        self.refused_while_testing: list[str] = []  # lines sent during the test: said again with its verdict
        self.begun_while_testing = False  # the entry held text when the verdict came: its next line is refused
        self.message = ""
        #: seconds from each valve's last safe stop to its decision on screen, and to its reports drawn
        self.decision_latencies_s: list[float] = []
        self.report_latencies_s: list[float] = []

    @property
    def testing(self) -> bool:
        """A test (or the rig self-check) is running."""
        return self._testing

    @testing.setter
    def testing(self, value: bool) -> None:
        self._testing = value
        # the live panel takes the whole width while a test runs: at 80 columns beside the side panel it wrapped,
        # and its lower half (the estimates, what decides the verdict) fell off a 24-row screen
        try:
            self.query_one("#side", Static).display = not value
        except (NoMatches, ScreenStackError):  # not composed yet
            pass

    # -- layout --------------------------------------------------------------------------------------------------

    def compose(self) -> ComposeResult:
        yield Static("", id="status")
        yield Label(PROMPTS[Step.VALVE_ID], id="prompt")
        yield ScanInput(placeholder="scan or type, then Enter", id="entry")
        yield Static("", id="message")
        yield Static("", id="verdict")
        yield Static("", id="words")
        with Horizontal(id="body"):
            yield Static("", id="live")
            yield Static("", id="side")
        yield Footer()

    def on_mount(self) -> None:
        self.set_interval(0.25, self._draw_live)
        self.set_interval(0.1, self._check_interrupt)
        self._show_status()
        if not self.shift.operator:
            self.push_screen(OperatorScreen(""), self._operator_named)
        else:
            self._ask_workshop()

    def _operator_named(self, name: str | None) -> None:
        if name:
            first = not self.shift.operator
            self.shift.operator = self.runner.operator = name
            self.remember(name)
            self._show_status()
            if first:
                self._ask_workshop()
        self.query_one("#entry", Input).focus()

    def _ask_workshop(self) -> None:
        """Once per station, after the operator: the workshop the customer's reports name."""
        if self.remember_workshop is None:
            self._start_of_shift()
            return
        self.push_screen(WorkshopScreen(ask_station=self.ask_station_name), self._workshop_named)

    def _workshop_named(self, workshop: tuple[str, ...] | None) -> None:
        remember, self.remember_workshop = self.remember_workshop, None
        if workshop is not None and remember is not None:
            try:
                path = (remember(*workshop[:2], shown_name=workshop[2]) if len(workshop) == 3
                        else remember(*workshop))
            except Exception as exc:  # noqa: BLE001 - the shift goes on; asked again next session
                self._say(f"the workshop could not be kept ({exc}): the reports name none until it is")
            else:
                self._say(f"workshop kept in {path} for every report ([station] shop, shop_address and "
                          "shown_name there change it)")
        self._start_of_shift()

    def _start_of_shift(self) -> None:
        self.query_one("#entry", Input).focus()
        if self.selfcheck is not None:
            if self.selfcheck.reference_valve() is None:  # said once; the shift goes on
                self._selfcheck_done(self.selfcheck.no_reference_words())
            else:
                self._ask_for_reference("the start of the shift")
        notice = priority_notice(self.runner.rig.simulated)
        if notice:  # once, at the start of the shift
            self._say_too(notice)

    def _show_status(self) -> None:
        variant = self.variant
        self.query_one("#status", Static).update(
            f"operator {self.shift.operator or '?'} | station {self.runner.station} | {self.runner.rig.describe()} | "
            f"pump type {variant.name} ({variant.pump.part_number}) | valves {len(self.shift.valves)}, tests "
            f"{self.shift.tests}")

    def _say(self, message: str) -> None:
        self.message = message
        self.query_one("#message", Static).update(Text(message))

    def _say_too(self, message: str) -> None:
        """Add to what the message line says (a question being asked stays on it)."""
        self._say(f"{self.message}; {message}" if self.message else message)

    # -- the prompts ---------------------------------------------------------------------------------------------

    def on_input_submitted(self, event: Input.Submitted) -> None:
        if event.input.id != "entry":
            return
        self.end_asked_at = None  # the shift goes on: a later Ctrl+Q asks again
        if self.end_when_drawn:
            self._say("the shift is ending: the last report is being finished")
            return
        if self.testing:  # never kept for the next prompt: it would be glued to the next scan
            typed = event.value.strip()
            if typed:
                self.refused_while_testing.append(typed)
            self._say(f"{typed!r} was not taken: a test is running. Scan it again after the verdict." if typed else
                      "a test is running: wait for its verdict")
            return
        if self.begun_while_testing:  # its first keys were typed during the test: part of it may be lost
            self.begun_while_testing = False
            typed = event.value.strip()
            if typed:
                self._say(f"{typed!r} was begun while the test ran and is not taken whole: scan it again")
                return
        if self.awaiting_reference:
            if event.value.strip():
                self._say(f"mount the reference valve {self.awaiting_reference} and press Enter alone (Esc skips "
                          "the check until it is due again)")
                return
            self._run_selfcheck_now()
            return
        answer = read_line(self.scan, event.value, ScanContext(self.part_numbers, self.scan_rules, self.shift.judged()))
        self._say(answer.message)
        if answer.switched_variant:
            self.variant = self.variant_loader(answer.scan.variant)
            self._show_status()
        self.scan = answer.scan
        if answer.refused and self.scan.pending and self.scan.step is Step.VALVE_ID:
            self._show_history(self.scan.pending)  # asked about: what the history knows of it helps decide
        if answer.noted:
            self._show_prompt()
            return
        if answer.refused or answer.switched_variant:
            return
        if self.scan.step is Step.PUMP_SERIAL:  # a new valve: the last verdict gives way to it
            self._clear_verdict()
            self._show_history(self.scan.valve_id)
        self._show_prompt()
        if answer.start_test:
            why = self.selfcheck.due() if self.selfcheck is not None else None
            if why:  # the rig is checked first; the valve stays scanned and is mounted after
                self.scan = replace(self.scan, step=Step.MOUNT)
                self._ask_for_reference(why)
                return
            job_ref = self.scan.job_ref
            self.scan = replace(self.scan, job_ref="")  # this valve's: the next valve's job is scanned with it
            self._test(self.scan.valve_id, self.scan.pump_serial, job_ref)

    def on_input_changed(self, event: Input.Changed) -> None:
        if event.input.id == "entry" and not event.value.strip():
            self.begun_while_testing = False  # emptied by hand: the next line is typed whole

    def _show_prompt(self) -> None:
        """The current step's prompt; mounting names the valve and pump scanned, so a wrong scan shows before the
        test."""
        if self.scan.step is Step.MOUNT:
            job = f" (job {self.scan.job_ref})" if self.scan.job_ref else ""
            self.query_one("#prompt", Label).update(f"Valve {self.scan.valve_id} on pump {self.scan.pump_serial}{job}. "
                                                    f"{PROMPTS[Step.MOUNT]}")
        else:
            self.query_one("#prompt", Label).update(PROMPTS[self.scan.step])

    def _typed_during_test(self) -> str:
        """What was typed while a test ran, when its verdict (or its failure) comes: lines sent then were refused
        and are named again; text still in the entry stays, but its line will be refused whole (the rest of a scan
        may come after the verdict). The words saying so ('' if nothing)."""
        words = [f"not taken during the test: {', '.join(repr(t) for t in self.refused_while_testing)}: scan again"
                 ] if self.refused_while_testing else []
        self.refused_while_testing = []
        typed = self.query_one("#entry", Input).value.strip()
        self.begun_while_testing = bool(typed)
        if typed:
            words.append(f"{typed!r} was begun during the test: Enter refuses it, then scan it again")
        return "; ".join(words)

    def action_back(self) -> None:
        self.end_asked_at = None
        if self.testing:
            return
        if self.awaiting_reference:
            self.awaiting_reference = ""
            why, due = self.awaiting_why, self.awaiting_due
            # a due check skipped is kept in the rig's ledger; one asked for by F6 was not due: nothing to keep
            kept = self.selfcheck.skip(why) if due and self.selfcheck is not None else ""
            self.shift.rig_checks.append(RigCheckEntry(None, "rig self-check: skipped by the operator", now_local()))
            due_still = self.selfcheck is not None and due and self.selfcheck.due()
            again = ("it is due: asked for again before the next valve's test" if due_still else
                     "asked for again when due; F6 runs it now")
            self.query_one("#live", Static).update(Text(f"{kept or 'rig self-check skipped'}; {again}",
                                                         style="bold yellow"))
        self.scan = Scan(variant=self.variant.name)
        self.query_one("#prompt", Label).update(PROMPTS[Step.VALVE_ID])
        self._say("back to the valve id")

    def _show_history(self, valve_id: str) -> None:
        lines = self.history_of(valve_id)
        side = self.query_one("#side", Static)
        if lines:
            side.update(Text("\n".join([f"valve {valve_id}, tested before:", *lines])))
        else:
            side.update(Text(f"valve {valve_id}: not tested before at this shop"))

    def _clear_verdict(self) -> None:
        self.verdict_shown = False
        verdict = self.query_one("#verdict", Static)
        verdict.update("")
        verdict.styles.background = None
        verdict.display = False  # its rows go to the live panel (at 80x24 its lower half was lost)
        self.query_one("#words", Static).update("")
        self.query_one("#live", Static).update("")

    # -- a test --------------------------------------------------------------------------------------------------

    def _test(self, valve_id: str, pump_serial: str, job_ref: str = "") -> None:
        self.testing = True
        self.observer = None  # the last test's panel is not this one's
        self.query_one("#live", Static).update("")
        first = "finishing the last valve's report first, then testing" if self.drawing.is_set() else "Testing"
        self.query_one("#prompt", Label).update(f"{first} valve {valve_id} ... keys typed now are not taken "
                                                "(the shift can end after its verdict)")
        self._run_valve(valve_id, pump_serial, self.variant, job_ref)

    def _new_observer(self, which: str) -> SnapshotObserver:
        self.observer = SnapshotObserver()
        self.observer_title = f"{which} of valve {self.scan.valve_id or self.last_valve_id}"
        if which == "retest":
            self.call_from_thread(self._say, "MARGINAL: near the limit. The bench tests the valve again now: "
                                             "leave it mounted.")
        return self.observer

    @work(thread=True, exclusive=True)
    def _run_valve(self, valve_id: str, pump_serial: str, variant: Any, job_ref: str = "") -> None:
        self.last_valve_id = valve_id
        if not self._wait_for_reports():
            self.call_from_thread(self._not_started, f"the test of valve {valve_id}")
            return
        try:
            done = self.runner.run_valve(variant, valve_id, pump_serial, observer=self._new_observer,
                                         job_ref=job_ref)
        except Exception as exc:  # noqa: BLE001 - the shift goes on; what failed is said on the screen
            self.call_from_thread(self._test_failed, valve_id, f"{type(exc).__name__}: {exc}")
            return
        self.call_from_thread(self._show_done, done)

    def _wait_for_reports(self) -> bool:
        """In a test's worker: the last valve's reports finished first (drawing beside a real-time loop would
        disturb its ticks; they take seconds, mostly while the next valve is scanned and mounted). False if the
        shift is ending meanwhile (Ctrl+Q, Ctrl-C, SIGTERM): the test is not started."""
        while self.drawing.is_set():
            time.sleep(0.05)
        return not (stop_requested() or self.end_when_drawn)

    def _not_started(self, what: str) -> None:
        self.testing = False
        self._say(f"{what} was not started: the shift is ending")
        self._show_prompt()

    def _draw_live(self) -> None:
        observer = self.observer
        if observer is None or not self.testing:
            return
        from edc_bench.ui.live import render_snapshot

        with observer.lock:
            panel = render_snapshot(observer.snapshot, self.observer_title)
        self.query_one("#live", Static).update(panel)

    def _test_failed(self, valve_id: str, why: str) -> None:
        self.testing = False
        typed = self._typed_during_test()
        self._say(f"the test of valve {valve_id} could not run: {why}. Check the rig and its cable, then scan "
                  f"the valve again.{' ' + typed if typed else ''}")
        self.query_one("#prompt", Label).update(PROMPTS[Step.VALVE_ID])

    def _show_done(self, done: ValveDone) -> None:
        self.testing = False
        self.last = done
        safe_stopped_at = self.observer.safe_stopped_at if self.observer is not None else None
        draw = self.runner.report and any(t.record_dir is not None for t in done.tests)
        if draw:  # before the details are shown, which say so
            self.drawing.set()
        final, cause = done.final, done.cause
        # the same valve INVALID again, both times for a cause the valve itself can cause: it may be seized (as its
        # record says: the report and `edc-bench test` say the same)
        seized = done.escalation or None
        words = seized or done.words
        verdict = self.query_one("#verdict", Static)
        verdict.display = True
        what = final if done.decision is None else f"{final}  (MARGINAL, retest {done.tests[-1].verdict})"
        verdict.update(Text(what + ("  (twice: the valve may be seized)" if seized is not None else ""),
                            style="bold white"))
        verdict.styles.background = VERDICT_COLOURS.get(final, "magenta")
        self.query_one("#words", Static).update(Text(words.upper() if final != "INVALID" or seized else words))
        self.query_one("#live", Static).update(self._details(done))
        typed = self._typed_during_test()
        self._say("; ".join(p for p in [*(p for t in done.tests for p in t.problems), typed] if p))
        self.verdict_shown = True
        self.shift.valves.append(ValveEntry(
            done.valve_id, done.pump_serial, done.variant, tuple(t.verdict for t in done.tests), final, words,
            tuple(str(t.record_dir) for t in done.tests if t.record_dir is not None), now_local(),
            str(cause) if cause is not None else ""))
        self._show_status()
        self.query_one("#prompt", Label).update(PROMPTS[Step.VALVE_ID])
        self.query_one("#entry", Input).focus()
        if safe_stopped_at is not None:
            self.decision_latencies_s.append(time.monotonic() - safe_stopped_at)
        if draw:
            self._draw_reports(done, safe_stopped_at)
        self._check_due()

    @work(thread=True, group="reports")
    def _draw_reports(self, done: ValveDone, safe_stopped_at: float | None) -> None:
        try:
            drawn = self.runner.draw_reports(done)
            problems = [p for t in drawn.tests for p in t.problems if p not in {q for t in done.tests
                                                                                for q in t.problems}]
        except Exception as exc:  # noqa: BLE001 - the records are kept; a report is drawn again from one
            drawn, problems = done, [f"the reports could not be drawn ({type(exc).__name__}: {exc}); draw them with: "
                                     "edc-bench report RECORD_FOLDER"]
        if safe_stopped_at is not None:
            self.report_latencies_s.append(time.monotonic() - safe_stopped_at)
        try:  # drawing ends on the screen's side, so a test waiting for it starts after the end of shift is decided
            self.call_from_thread(self._reports_drawn, drawn, problems)
        finally:
            self.drawing.clear()  # the app gone meanwhile, or the call failed: no one waits on it for ever

    def _reports_drawn(self, done: ValveDone, problems: list[str]) -> None:
        """The valve's reports are drawn (or what failed): its details say so while its verdict is on screen."""
        self.drawing.clear()
        if self.last is not None and self.last.tests[0].record_dir == done.tests[0].record_dir:
            self.last = done
            if self.verdict_shown and not self.testing:
                self.query_one("#live", Static).update(self._details(done))
        if problems:  # added: the message line may hold a question being asked
            self._say_too("; ".join(problems))
        if self.end_when_drawn and not self.testing:
            self._end_shift()

    def _details(self, done: ValveDone) -> Text:
        lines = []
        for n, test in enumerate(done.tests):
            label = "test" if n == 0 else "retest"
            # a pair's tests under its decision: their verdicts only, never a test's own "retest" line beside it
            lines.append(f"{label}: {test.verdict}" if done.decision is not None
                         else f"{label}: {test.verdict}, {test.result.advice.words}")
            if test.record_dir is not None:
                report = (", report ready (F5 prints it)" if test.report_pdf is not None else
                          ", report being drawn" if self.drawing.is_set() else "")
                lines.append(f"  record {test.record_dir.name}{report}")
        if done.decision is not None:
            lines.append(f"decision: {done.decision.verdict} by the pump type's rule {done.decision.rule}")
        lines.append(f"records folder: {self.runner.out_dir.resolve()}")
        return Text("\n".join(lines))

    # -- the rig self-check --------------------------------------------------------------------------------------

    def _check_due(self) -> None:
        if self.selfcheck is None:
            return
        why = self.selfcheck.due()
        if why:
            self._ask_for_reference(why)

    def _ask_for_reference(self, why: str, due: bool = True) -> None:
        reference = self.selfcheck.reference_valve() if self.selfcheck is not None else None
        if reference is None:
            return
        if self.awaiting_reference and self.awaiting_due and not due:  # F6 on a due check: it stays the due one
            return
        self.awaiting_reference, self.awaiting_why, self.awaiting_due = reference, why, due
        self.query_one("#prompt", Label).update(f"Rig self-check ({why}): mount the reference valve {reference}, "
                                                "then press Enter")

    def action_rig_selfcheck(self) -> None:
        if not self.testing and self.selfcheck is not None:
            if self.selfcheck.reference_valve() is None:
                self._selfcheck_done(self.selfcheck.no_reference_words())
            else:
                self._ask_for_reference(ASKED_FOR, due=False)

    def _run_selfcheck_now(self) -> None:
        self.testing = True
        self.observer = None  # no live panel: the last test's would look like this one
        self.query_one("#prompt", Label).update(f"Rig self-check with the reference valve {self.awaiting_reference} "
                                                "...")
        self.awaiting_reference = ""
        self._run_selfcheck()

    @work(thread=True, exclusive=True)
    def _run_selfcheck(self) -> None:
        if not self._wait_for_reports():
            self.call_from_thread(self._not_started, "the rig self-check")
            return
        try:
            words = self.selfcheck.run()
        except Exception as exc:  # noqa: BLE001 - said on the screen; the shift goes on
            words = SelfCheckWords(False, f"rig self-check: could not run ({type(exc).__name__}: {exc})")
        self.call_from_thread(self._selfcheck_done, words)

    def _selfcheck_done(self, words: SelfCheckWords) -> None:
        self.testing = False
        typed = self._typed_during_test()
        self.shift.rig_checks.append(RigCheckEntry(words.go, words.words, now_local()))
        style = {True: "green", False: "red"}.get(words.go, "yellow")
        line = words.words  # a whole line, "rig self-check: ..." (SelfCheckWords)
        # in the wide panel (no test's figures are on it now): a NO-GO's words whole at 80x24, not in a narrow column
        self.query_one("#live", Static).update(Text(line, style=f"bold {style}"))
        self._show_prompt()
        self.query_one("#entry", Input).focus()
        if words.go is False:
            self._say("the rig is not fit to judge valves: do what the self-check says, then F6 to check again"
                      + (f"; {typed}" if typed else ""))
        elif typed:
            self._say(typed)

    # -- keys ----------------------------------------------------------------------------------------------------

    def action_change_operator(self) -> None:
        if not self.testing:
            self.push_screen(OperatorScreen(self.shift.operator), self._operator_named)

    def action_print_report(self) -> None:
        done = self.last
        pdfs = [t.report_pdf for t in done.tests if t.report_pdf is not None] if done is not None else []
        if not pdfs:
            records = [t.record_dir for t in done.tests if t.record_dir is not None] if done is not None else []
            self._say("the report is being drawn: press F5 again when it is ready" if self.drawing.is_set() else
                      f"the report of {records[-1].name} could not be drawn: edc-bench report {records[-1]} draws it"
                      if records else "no report to print yet: test a valve first")
            return
        lp = shutil.which("lp")
        if lp is None:
            self._say(f"no printer command (lp) on this station: the report is {pdfs[-1]}")
            return
        try:
            result = subprocess.run([lp, str(pdfs[-1])], capture_output=True, text=True, timeout=30, check=False)
        except (subprocess.TimeoutExpired, OSError) as exc:
            self._say(f"the printer did not take the report ({type(exc).__name__}): it is {pdfs[-1]}")
            return
        self._say(f"sent to the printer: {pdfs[-1].name}" if result.returncode == 0 else
                  f"the printer refused the report ({(result.stderr or result.stdout).strip()}): it is {pdfs[-1]}")

    def action_end_shift(self) -> None:
        if self.testing:
            self._say("a test is running: end the shift after its verdict (Ctrl+Q twice)")
            return
        asked = self.end_asked_at
        if asked is None or time.monotonic() - asked > END_CONFIRM_S:  # a key next to others: asked, not obeyed
            self.end_asked_at = time.monotonic()
            self._say(f"End the shift? Press Ctrl+Q again within {END_CONFIRM_S:g} s to end it and write its "
                      "summary; scanning goes on as before")
            return
        self._end_shift()

    async def action_quit(self) -> None:
        """Textual's own quit (its key, a window's close): the shift's end, as Ctrl+Q."""
        self.action_end_shift()

    def _end_shift(self) -> None:
        if self.drawing.is_set():  # a report half drawn is a report lost: the shift ends once it is whole
            self.end_when_drawn = True
            self._say("finishing the last report: the shift ends then")
            return
        try:
            self.summary_file = self.shift.write(self.shift_folder)
        except OSError as exc:
            self._say(f"the shift summary could not be written ({exc}); it is shown below")
        self.exit()

    def _check_interrupt(self) -> None:
        """Ctrl-C or SIGTERM sent to the session's process (``edc-bench session`` holds them back,
        :func:`~edc_bench.runtime.signals.interrupt_guard`): a test running sees it too and ends as an abort, SAFE
        sent and its record kept; once no test runs, the shift ends as by Ctrl+Q, its summary saying why."""
        if not stop_requested() or self.shift.interrupted:
            return
        if self.testing:
            self._say("interrupted (Ctrl-C or SIGTERM): the test stops safely and keeps its record; the shift ends "
                      "then")
            return
        self.shift.interrupted = True
        if not self.end_when_drawn:  # else the shift ends once the last report is drawn
            self._end_shift()
