"""The live panel (rich) and the verdict panel at the end of a test.

The loop only copies figures into a :class:`~edc_bench.ui.snapshot.Snapshot`
(every 100 ticks, a few microseconds); rich draws it from its own thread four
times a second. While the panel is up, the interpreter's thread switch
interval is cut to 0.2 ms, so a redraw cannot hold the loop's thread off for
the default 5 ms when its next deadline comes.
"""

from __future__ import annotations

import math
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from rich.console import Console, Group
from rich.panel import Panel
from rich.progress_bar import ProgressBar
from rich.table import Table
from rich.text import Text

from edc_bench.ui.snapshot import PHASES, Snapshot

_BARS = "▁▂▃▄▅▆▇█"
VERDICT_STYLES = {"PASS": "bold white on green", "MARGINAL": "bold black on yellow", "FAIL": "bold white on red",
                  "INVALID": "bold white on magenta", "UNCLASSIFIED": "bold"}


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
    if s.ticks:
        bar = ProgressBar(total=s.ticks, completed=s.tick + 1, width=40)
        grid.add_row("time", Group(Text(f"{s.t_s:5.1f} s of {s.duration_s:g} s, {s.time_left_s:4.1f} s left"), bar))
        error_um = (s.reference_mm - s.position_mm) * 1e3
        both = list(s.rack_history) + list(s.reference_history)
        lo, hi = (min(both), max(both)) if both else (0.0, 1.0)
        grid.add_row("rack", f"{s.position_mm:7.3f} mm   reference {s.reference_mm:7.3f} mm   error {error_um:+6.0f} um")
        grid.add_row("", Text(sparkline(s.rack_history, lo, hi), style="cyan"))
        grid.add_row("", Text(sparkline(s.reference_history, lo, hi), style="dim"))
        grid.add_row("coil", f"{s.current_a:6.3f} A   drive {s.drive_v:+6.3f} V "
                             f"(feedforward {s.feedforward_v:+6.3f}, PID {s.feedback_v:+6.3f})")
        grid.add_row("af", f"{s.af:9.5f} V        {_settled(s.af_history)}")
        grid.add_row("", Text(sparkline(s.af_history), style="yellow"))
        grid.add_row("a1", f"{s.a1:9.6f} V s/mm   {_settled(s.a1_history)}")
        grid.add_row("", Text(sparkline(s.a1_history), style="yellow"))
        late_style = "red" if s.overruns else "green"
        grid.add_row("loop", Text(f"worst lateness {s.worst_lateness_recent_us:5.0f} us now, "
                                  f"{s.worst_lateness_us:5.0f} us in all; {s.overruns} overruns", style=late_style))
        bus_style = "red" if s.missed_replies or s.bad_replies else "green"
        grid.add_row("bus", Text(f"{s.missed_replies} replies missing, {s.bad_replies} bad, "
                                 f"{s.heartbeats} heartbeats", style=bus_style))
    return Panel(grid, title=title, border_style="blue")


def verdict_panel(result: Any, record_dir: Path | None) -> Panel:
    """The end of a test: the verdict, why, the figures behind it, and where the record is."""
    body = Table.grid(padding=(0, 2))
    body.add_column(style="bold", justify="right")
    body.add_column()
    body.add_row("verdict", Text.assemble((f" {result.verdict} ", VERDICT_STYLES.get(result.verdict, "bold"))))
    for n, reason in enumerate(result.reasons):
        body.add_row("why" if n == 0 else "", reason)
    f = result.features
    if not math.isnan(f.get("af", math.nan)):
        line = f"af {f['af']:.5f} V, a1 {f['a1']:.6f} V s/mm"
        if result.classification:
            rel = result.classification["features_rel"]
            line += f"   ({rel['af'] - 1:+.0%} and {rel['a1'] - 1:+.0%} against a new valve)"
        body.add_row("valve", line)
    t = result.timing
    if t.get("ticks"):
        body.add_row("timing", f"{t['ticks']} ticks, lateness p99 {t['lateness_p99_us']:.0f} us, "
                               f"{t['overruns']} overruns, {result.outcome.missed_replies} replies missing")
    if record_dir is not None:
        body.add_row("record", str(record_dir))
        body.add_row("next", f"edc-bench report {record_dir}")
    style = {"PASS": "green", "MARGINAL": "yellow", "FAIL": "red"}.get(result.verdict, "magenta")
    return Panel(body, title=f"valve {result.valve_id or '?'} on {result.variant.name}", border_style=style)


class LiveView:
    """The live panel as a :class:`~edc_bench.control.loop.LoopObserver`; use as a context manager.

    Parameters
    ----------
    title : str
        Panel title (variant, valve, rig).
    console : rich.console.Console, optional
        Where to draw (stdout by default).
    """

    def __init__(self, title: str, console: Console | None = None) -> None:
        from rich.live import Live

        self.title = title
        self.console = console or Console()
        self.snapshot = Snapshot()
        self._live = Live(get_renderable=lambda: render_snapshot(self.snapshot, self.title), console=self.console,
                          refresh_per_second=4, transient=False)
        self._switch_interval = sys.getswitchinterval()

    def __enter__(self) -> LiveView:
        sys.setswitchinterval(2e-4)
        self._live.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.snapshot.enter("done")
        self._live.stop()
        sys.setswitchinterval(self._switch_interval)

    def phase(self, name: str) -> None:
        """Show the phase."""
        self.snapshot.enter(name)

    def tick(self, k: int, loop: Any) -> None:
        """Copy the figures; drawing happens on rich's thread."""
        self.snapshot.update(k, loop)
