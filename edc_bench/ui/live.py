"""The live panel (rich) and the verdict panel at the end of a test.

The loop only reads a few figures every 100 ticks and hands them to a child
process, which draws them with rich four times a second (see
:class:`LiveView` for why not a thread).
"""

from __future__ import annotations

import math
import os
import pickle
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from rich.console import Console, Group
from rich.panel import Panel
from rich.progress_bar import ProgressBar
from rich.table import Table
from rich.text import Text

from edc_bench.engine.outcome import PeriodDecision, StopReason
from edc_bench.identification.analysis import model_fit_line
from edc_bench.identification.coil_check import coil_line
from edc_bench.records.baseline_text import baseline_line
from edc_bench.records.schema import StopSummary
from edc_bench.runtime.loop import Phase
from edc_bench.ui.snapshot import PHASES, Snapshot, read_tick
from edc_bench.verdict.verdicts import Verdict

_BARS = "▁▂▃▄▅▆▇█"
VERDICT_STYLES = {Verdict.PASS: "bold white on green", Verdict.MARGINAL: "bold black on yellow",
                  Verdict.FAIL: "bold white on red", Verdict.INVALID: "bold white on magenta",
                  Verdict.UNCLASSIFIED: "bold"}


def sparkline(values: Sequence[float], lo: float | None = None, hi: float | None = None, width: int = 50) -> str:
    """Values as a line of block characters (the last ``width``), scaled to ``lo``..``hi``."""
    data = [v for v in list(values)[-width:] if v == v]
    if not data:
        return ""
    lo = min(data) if lo is None else lo
    hi = max(data) if hi is None else hi
    span = (hi - lo) or 1.0
    return "".join(_BARS[min(len(_BARS) - 1, max(0, int((v - lo) / span * (len(_BARS) - 1) + 0.5)))] for v in data)


def _settled(history: Sequence[float], points: int = 20) -> str:
    """How far the last ``points`` values stray from the latest, in percent."""
    recent = [v for v in history[-points:] if v == v]
    if len(recent) < points or not recent[-1]:
        return "settling"
    spread = max(abs(v - recent[-1]) for v in recent) / abs(recent[-1])
    return f"within {spread:.1%} over the last {points / 10:g} s"


#: What the bench waits for before the first tick, by phase (#53: the first valve sat on "connect" for 18 s with
#: nothing else on screen).
WAITING_FOR = {
    Phase.CONNECT: "the rig's bus to open and the test to be prepared (the pump type's controller and its gain "
                   "check, the classifier)",
    Phase.WAIT_READY: "the rig's READY heartbeat: is the rig powered on, its CAN cable plugged in, no fault latched? "
                      "(the test gives up after the pump type's acceptance.ready_timeout_s)",
}


def render_snapshot(s: Snapshot, title: str) -> Panel:
    """The live panel for one state of the test."""
    steps = Text()
    for name in PHASES:
        if name == s.phase:
            steps.append(f" {name} ", style="bold reverse")
        elif name in s.phases_done:
            steps.append(f" {name} ✓ ", style="green")
        else:
            steps.append(f" {name} ", style="dim")
    grid = Table.grid(padding=(0, 2))
    grid.add_column(style="bold", justify="right")
    grid.add_column()
    grid.add_row("phase", steps)
    waiting = WAITING_FOR.get(s.phase) if not s.ticks else None
    if waiting:  # before the first tick nothing moves on screen: say what the bench waits for
        grid.add_row("waiting for", Text(waiting))
    if s.ticks:
        bar = ProgressBar(total=s.ticks, completed=s.tick + 1, width=40)
        if s.expected_end_s == s.expected_end_s:  # early stop: when the verdict is expected to be known
            when = f"{s.t_s:5.1f} s, {s.time_left_words}"
        else:
            when = f"{s.t_s:5.1f} s of {s.duration_s:g} s, {s.time_left_words}"
        grid.add_row("time", Group(Text(when), bar))
        error_um = (s.reference_mm - s.position_mm) * 1e3
        both = list(s.rack_history) + list(s.reference_history)
        lo, hi = (min(both), max(both)) if both else (0.0, 1.0)
        grid.add_row("rack", f"{s.position_mm:7.3f} mm   reference {s.reference_mm:7.3f} mm   error {error_um:+6.0f} um")
        grid.add_row("", Text(sparkline(s.rack_history, lo, hi), style="cyan"))
        grid.add_row("", Text(sparkline(s.reference_history, lo, hi), style="dim"))
        grid.add_row("coil", f"{s.current_a:6.3f} A   drive {s.drive_v:+6.3f} V "
                             f"(feedforward {s.feedforward_v:+6.3f}, PID {s.feedback_v:+6.3f})")
        grid.add_row("verdict on", period_fit_line(s.period_fit))
        grid.add_row("af online", f"{s.af:9.5f} V        {_settled(s.af_history)}")
        grid.add_row("", Text(sparkline(s.af_history), style="yellow"))
        grid.add_row("a1 online", f"{s.a1:9.6f} V s/mm   {_settled(s.a1_history)}")
        grid.add_row("", Text(sparkline(s.a1_history), style="yellow"))
        late_style = "red" if s.ticks_late_or_lost else "green"
        grid.add_row("loop", Text(f"worst lateness {s.worst_lateness_recent_us:5.0f} us now, "
                                  f"{s.worst_lateness_us:5.0f} us in all; {s.ticks_late_or_lost} ticks late or lost",
                                  style=late_style))
        bus_style = "red" if s.missed_replies or s.bad_replies else "green"
        grid.add_row("bus", Text(f"{s.missed_replies} replies missing, {s.bad_replies} bad, "
                                 f"{s.heartbeats} heartbeats", style=bus_style))
    return Panel(grid, title=Text(title), border_style="blue")  # the title holds the valve id: never markup


def period_fit_line(fit: PeriodDecision | None) -> Text:
    """What the verdict will rest on, as the stop rule last saw it: af and a1 over whole periods, against a new
    valve, with their interval (the online estimates below only keep the feedforward right)."""
    if fit is None:
        return Text("af and a1 over whole excitation periods, from the first decision on", style="dim")
    verdict = f": {fit.verdict} so far" if fit.verdict else ": not settled yet"
    return Text(f"af {fit.af_rel - 1:+.1%} +/-{fit.af_half_width_rel:.1%}, a1 {fit.a1_rel - 1:+.1%} "
                f"+/-{fit.a1_half_width_rel:.1%} against a new valve, {fit.periods} periods{verdict}")


def stop_line(stop: StopSummary) -> str:
    """Why and when a test ended, in words."""
    at = f"after {stop.time_s:.1f} s of at most {stop.max_s:g} s"
    reason = stop.reason
    if reason == StopReason.VERDICT_CERTAIN:
        return f"{at}: af and a1 known well enough that the verdict cannot change ({stop.periods} periods)"
    if reason == StopReason.MODEL_DOES_NOT_FIT:
        return f"{at}: the model does not fit this pump; a longer test would not help"
    if reason == StopReason.FULL_LENGTH:
        return f"{at}: full length" + (" (--full-length)" if stop.full_length else
                                       f" ({stop.why_full_length})" if stop.why_full_length else "")
    return f"{at}: aborted"


def verdict_panel(result: Any, record_dir: Path | None) -> Panel:
    """The end of a test: the verdict, why, the figures behind it, and where the record is."""
    body = Table.grid(padding=(0, 2))
    body.add_column(style="bold", justify="right")
    body.add_column()
    body.add_row("verdict", Text.assemble((f" {result.verdict} ", VERDICT_STYLES.get(result.verdict, "bold")),
                                          ("  " + result.advice.words, "bold")))
    for n, reason in enumerate(result.reasons):
        body.add_row("why" if n == 0 else "", reason)
    f = result.features
    if f.af is not None and not math.isnan(f.af):  # af identified (a1 shown as it is)
        line = f"af {f.af:.5f} V, a1 {f.a1:.6f} V s/mm"
        if result.classification:
            rel = result.classification.features_rel
            line += f"   ({rel.af - 1:+.0%} and {rel.a1 - 1:+.0%} against a new valve)"
        body.add_row("valve", line)
        body.add_row("", "af and a1 referred to the reference coil "
                         f"({result.variant.coil.resistance_ohm:g} ohm at 20 degC): this coil's resistance is "
                         "taken out of them")
    if result.judgement.coil is not None:
        body.add_row("coil", coil_line(result.judgement.coil))
    if result.judgement.baseline is not None:
        nominal = result.judgement.baseline.calibrated is False
        body.add_row("baseline", Text(baseline_line(result.judgement.baseline), style="bold magenta" if nominal else ""))
    stop = result.stop
    if stop is not None:
        body.add_row("ended", stop_line(stop))
    ident = result.identification
    if ident is not None and ident.model_fit is not None:
        fit = ident.model_fit
        body.add_row("model fit", Text(model_fit_line(fit, ratio_decimals=1) + ("" if fit.fits else ": DOES NOT FIT"),
                                       style="" if fit.fits else "bold magenta"))
    t = result.timing
    if t.ticks:
        body.add_row("timing", f"{t.ticks} ticks, lateness p99 {t.lateness_p99_us:.0f} us, "
                               f"{t.ticks_late + result.outcome.ticks_lost} ticks late or lost, {result.outcome.missed_replies} replies missing")
    if record_dir is not None:
        body.add_row("record", Text(str(record_dir)))
        body.add_row("next", Text(f"edc-bench report {record_dir}"))
    style = {Verdict.PASS: "green", Verdict.MARGINAL: "yellow", Verdict.FAIL: "red"}.get(result.verdict, "magenta")
    # the valve id as the technician typed it, never read as rich markup
    return Panel(body, title=Text(f"valve {result.valve_id or '?'} on {result.variant.name}"), border_style=style)


def decision_panel(decision: Any, first_verdict: str, retest_verdict: str) -> Panel:
    """What a MARGINAL and its retest decide together (:class:`~edc_bench.verdict.retest.Decision`), big."""
    body = Text.assemble((f" {decision.verdict} ", VERDICT_STYLES.get(decision.verdict, "bold")),
                         ("  " + decision.words, "bold"),
                         f"\nfirst test {first_verdict}, retest {retest_verdict}; the variant's rule {decision.rule}")
    style = {Verdict.PASS: "green", Verdict.FAIL: "red"}.get(decision.verdict, "magenta")
    return Panel(body, title="decision", border_style=style)


class LiveView:
    """The live panel as a :class:`~edc_bench.runtime.loop.LoopObserver`; use as a context manager.

    The panel is drawn by a child process. Drawing in the loop's process,
    even from another thread, cost a real-time test its timing: the drawing
    thread takes the interpreter lock while the loop spins towards its
    deadline or waits for its reply (at 1 kHz against the rig process, p99
    lateness above a tick, and aborts). The
    loop writes a few hundred bytes every 100 ticks into a non-blocking
    pipe; if the drawing process falls behind or dies, updates are dropped,
    never waited for.

    Parameters
    ----------
    title : str
        Panel title (variant, valve, rig).
    """

    def __init__(self, title: str) -> None:
        self.title = title
        self._proc: Any = None
        self._fd: int | None = None

    def __enter__(self) -> LiveView:
        import subprocess
        import sys

        # its stdin is our pipe; its stdout is our terminal; it closes `ready` once drawn
        ready_r, ready_w = os.pipe()
        self._proc = subprocess.Popen([sys.executable, "-m", "edc_bench.ui.live", self.title, str(ready_w)],
                                      stdin=subprocess.PIPE, pass_fds=(ready_w,))
        os.close(ready_w)
        # Wait until it has imported and drawn: starting the panel costs a CPU for a few hundred
        # milliseconds, which must not overlap the first ticks of a real-time test.
        import select

        select.select([ready_r], [], [], 5.0)
        os.close(ready_r)
        self._fd = self._proc.stdin.fileno()
        os.set_blocking(self._fd, False)
        return self

    def __exit__(self, *exc: object) -> None:
        self._send(("done", None))
        if self._proc is not None:
            try:
                self._proc.stdin.close()
            except OSError:
                pass
            self._fd = None
            try:
                self._proc.wait(timeout=3.0)
            except Exception:
                self._proc.kill()  # a panel that does not end never holds the test's end
                try:
                    self._proc.wait(timeout=1.0)  # reaped: no zombie, and its returncode says it was killed
                except Exception:  # noqa: BLE001 - nothing more to do for a panel
                    pass

    def _send(self, message: tuple[str, Any]) -> None:
        if self._fd is None:
            return
        data = pickle.dumps(message, protocol=pickle.HIGHEST_PROTOCOL)
        try:
            # one write under PIPE_BUF (4096 bytes) is atomic: all of it or EAGAIN
            os.write(self._fd, len(data).to_bytes(4, "little") + data)
        except BlockingIOError:
            pass  # the panel is behind: drop this update rather than wait
        except OSError:
            self._fd = None  # the panel is gone (terminal closed): the test goes on without it

    def phase(self, name: str) -> None:
        """Show the phase."""
        self._send(("phase", name))

    def tick(self, k: int, loop: Any) -> None:
        """Send tick ``k``'s figures to the panel."""
        self._send(("tick", read_tick(k, loop)))


def _messages(fd: int, timeout_s: float) -> list[tuple[str, Any]]:
    """Messages waiting on ``fd`` (waits up to ``timeout_s`` for the first); ``("done", None)`` at end of file."""
    import select

    ready, _, _ = select.select([fd], [], [], timeout_s)
    if not ready:
        return []
    out, buffer = [], b""
    while True:
        chunk = os.read(fd, 65536)
        if not chunk:
            return [*out, ("done", None)]
        buffer += chunk
        while len(buffer) >= 4 and len(buffer) >= 4 + int.from_bytes(buffer[:4], "little"):
            size = int.from_bytes(buffer[:4], "little")
            out.append(pickle.loads(buffer[4:4 + size]))
            buffer = buffer[4 + size:]
        if not buffer and not select.select([fd], [], [], 0)[0]:
            return out


def _step_aside() -> None:
    """Run the panel only on CPU time nobody else wants (Linux SCHED_IDLE; else the lowest nice).

    Woken four times a second, a normal process would preempt the loop (or,
    in simulation, the rig process) for the few milliseconds a redraw takes,
    and ticks overrun.
    """
    try:
        os.sched_setscheduler(0, os.SCHED_IDLE, os.sched_param(0))
    except (AttributeError, OSError):
        try:
            os.nice(19)
        except OSError:
            pass


def _draw(fd: int, title: str, ready_fd: int | None = None) -> None:
    """The drawing process: apply what the loop sends, redraw four times a second, stop on "done"."""
    import signal

    from rich.live import Live

    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the test's to handle, not the panel's
    _step_aside()
    snapshot = Snapshot()
    with Live(render_snapshot(snapshot, title), console=Console(), auto_refresh=False, transient=False) as live:
        live.refresh()
        if ready_fd is not None:
            os.close(ready_fd)  # the test may start
        while True:
            done = False
            for kind, payload in _messages(fd, 0.25):
                if kind == "phase":
                    snapshot.enter(payload)
                elif kind == "tick":
                    snapshot.apply(payload)
                else:
                    done = True
            live.update(render_snapshot(snapshot, title), refresh=True)
            if done:
                return


if __name__ == "__main__":
    import sys

    _draw(sys.stdin.fileno(), sys.argv[1] if len(sys.argv) > 1 else "edc-bench test",
          int(sys.argv[2]) if len(sys.argv) > 2 else None)
