"""A rig check's outputs: the table on the terminal, the JSON, and the one-page PDF a rig builder files."""

from __future__ import annotations

import dataclasses
import json
import textwrap
from pathlib import Path
from typing import Any

from edc_bench.rigcheck import RigCheckReport
from edc_bench.rigcheck.checks import CheckResult


def mark(result: CheckResult) -> str:
    """PASS, FAIL, or "not checked"."""
    return {True: "PASS", False: "FAIL", None: "not checked"}[result.passed]


def verdict_line(report: RigCheckReport) -> str:
    """GO, or NO-GO naming the rules broken."""
    if not report.frames_received:
        return ("NO-GO: no frame came from the rig on this bus in the whole check: is the rig powered and "
                "connected, and the bus's bit rate the rig's?")
    if report.go:
        checked = sum(r.passed is not None for r in report.results)
        return f"GO: the rig kept every ICD rule checked ({checked} checks)"
    return "NO-GO: " + "; ".join(f"{r.title} ({r.measured})" for r in report.failed)


def as_json(report: RigCheckReport) -> dict[str, Any]:
    """The report as JSON-ready data."""
    from edc_bench.records.writer import json_safe

    return json_safe({"verdict": "GO" if report.go else "NO-GO", "when": report.when, "variant": report.variant,
                      "bus": report.where, "bench_worst_late_ms": report.worst_late_ms,
                      "frames_received": report.frames_received,
                      "expected": report.expectations,
                      "checks": [{**dataclasses.asdict(r), "result": mark(r)} for r in report.results]})


def print_table(report: RigCheckReport) -> None:
    """The checks as a table, then the verdict."""
    from rich.console import Console
    from rich.table import Table
    from rich.text import Text

    table = Table(title=f"ICD v1 conformance: {report.where} (variant {report.variant})", show_lines=False)
    table.add_column("check", style="bold", no_wrap=True)
    table.add_column("result", no_wrap=True)
    table.add_column("measured")
    styles = {True: "bold green", False: "bold white on red", None: "yellow"}
    for r in report.results:
        table.add_row(r.title, Text(mark(r), style=styles[r.passed]), r.measured)
    console = Console()
    console.print(table)
    style = "bold white on green" if report.go else "bold white on red"
    if not report.frames_received:  # nothing to say about rules: nothing answered
        console.print(Text(" NO-GO ", style=style), verdict_line(report).removeprefix("NO-GO: "))
        return
    for r in report.failed:  # the rule each failed check holds the rig to
        console.print(Text.assemble((f"{r.title}: ", "bold"), f"the ICD says: {r.rule}"))
    console.print(Text(f" {'GO' if report.go else 'NO-GO'} ", style=style),
                  "the rig kept every ICD rule checked" if report.go else
                  f"{len(report.failed)} check(s) failed: fix the firmware before the first valve")


def write_files(report: RigCheckReport, folder: Path) -> tuple[Path, Path]:
    """rig-check.json and the one-page rig-check.pdf in ``folder`` (made if missing)."""
    from edc_bench.paths import atomic_write

    folder.mkdir(parents=True, exist_ok=True)
    json_path, pdf_path = folder / "rig-check.json", folder / "rig-check.pdf"
    text = json.dumps(as_json(report), indent=2) + "\n"
    atomic_write(json_path, lambda f: f.write(text.encode()))
    atomic_write(pdf_path, lambda f: _pdf(report, f))
    return json_path, pdf_path


def _pdf(report: RigCheckReport, out: Any) -> None:
    """One A4 page: the verdict, what the rig was held to, and every check with its figure and rule."""
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib.figure import Figure

    fig = Figure(figsize=(8.27, 11.69))
    ax = fig.add_axes((0.07, 0.05, 0.86, 0.91))
    ax.axis("off")
    y = 1.0

    def lines(text: str, width: int, size: float, x: float = 0.0, **style: Any) -> None:
        """``text`` wrapped at ``width`` characters from ``x``, moving down the page."""
        nonlocal y
        for line in textwrap.wrap(text, width):
            ax.text(x, y, line, fontsize=size, va="top", **style)
            y -= size * 0.0019

    lines("ICD v1 conformance: rig check", 60, 16, weight="bold")
    y -= 0.005
    exp = report.expectations
    lines(f"{report.when}; bus: {report.where}; held to variant {report.variant}: watchdog {exp.get('watchdog_ms')} "
          f"ms, heartbeat every {exp.get('heartbeat_period_ms')} ms, replies used up to "
          f"{exp.get('max_reply_age_ms')} ms old; hold drive {exp.get('hold_drive_v')} V "
          f"({exp.get('hold_current_a')} A, half the spring's preload)", 120, 7.5, color="0.3")
    y -= 0.01
    colour = "#1b7f3b" if report.go else "#b3261e"
    lines(verdict_line(report), 80, 11, weight="bold", color=colour)
    y -= 0.012
    colours = {True: "#1b7f3b", False: "#b3261e", None: "#8a6d00"}
    for r in report.results:
        ax.text(0.0, y, mark(r), fontsize=8.5, weight="bold", color=colours[r.passed], va="top")
        lines(r.title, 90, 8.5, weight="bold", x=0.14)
        lines(r.measured, 110, 7.5, x=0.14)
        lines(r.rule, 125, 6.5, x=0.14, color="0.4")
        y -= 0.006
    y = -0.01
    lines("edc-bench rig-check: black-box checks of firmware_proto/PROTOCOL.md (ICD v1). The rack is never driven "
          "beyond a hold below the spring's preload; the rig is left in SAFE.", 140, 6.5, color="0.4")
    fig.savefig(out, format="pdf")


__all__ = ["as_json", "mark", "print_table", "verdict_line", "write_files"]
