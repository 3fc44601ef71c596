"""The one-page customer report of a test: PDF for printing, PNG for screens and mail.

Drawn with matplotlib on an A4 page from the record folder alone (record.json
and the trace; no variant file, no model, no recomputation): identity
and versions, the verdict with its probability and distance to the
boundary, the parameter table with uncertainties and the change against
the reference (the new-valve baseline for af and a1, the data-sheet
nominal for the others, as the paper's Table 1 compares valves), the
tracking and convergence plots (paper Figs. 3-5) and the valve's point on
the decision plane (Fig. 7).
"""

from __future__ import annotations

import math
import textwrap
from pathlib import Path
from typing import Any

import numpy as np

from edc_bench.paths import atomic_write
from edc_bench.records.baseline_text import baseline_line
from edc_bench.records.reader import load_record, load_trace
from edc_bench.records.schema import Record
from edc_bench.verdict.verdicts import Verdict

REPORT_PDF = "report.pdf"
REPORT_PNG = "report-page.png"
_VERDICT_COLOURS = {Verdict.PASS: "#2e7d32", Verdict.MARGINAL: "#f9a825", Verdict.FAIL: "#c62828",
                    Verdict.INVALID: "#6a1b9a"}
_ID_COLUMN_CHARS = 40  # characters of 7.5 pt text in the identity block's value column (two lines at most: the
# row's room; record.json holds the whole value)
_UNITS = {"a3": "V s^3/mm", "a2": "V s^2/mm", "a1": "V s/mm", "a0": "V/mm", "b": "V", "af": "V"}


def _reference_values(record: Record) -> dict[str, tuple[float, str]]:
    """Per parameter: the value it is compared with, and where that comes from, as the test recorded them."""
    return {name: (entry.value, entry.source) for name, entry in record.reference_values.items()
            if entry.value is not None}


def _identity_lines(record: Record, folder: Path) -> list[tuple[str, str]]:
    identity, cls = record.identity, record.classification
    pump = (record.config or {}).get("pump")
    description = str(pump.get("description", "")) if isinstance(pump, dict) else ""
    if cls is not None and cls.model:
        model = f"{cls.model} classifier {cls.model_file or '?'}, sha256 {(cls.model_sha256 or '')[:12] or 'not recorded'}"
    else:
        model = "not classified"
    return [
        ("Pump", f"{record.variant or '?'}, part number {record.part_number or '?'}"),
        ("", description[:60]),
        ("Pump serial", identity.pump_serial or "-"),
        ("Valve", record.valve_id or "-"),
        ("Date", (record.started_at or "?").replace("T", " ").replace("+00:00", " UTC")),
        ("Station / operator", f"{identity.station or '-'} / {identity.operator or '-'}"),
        ("Software", f"edc-bench {record.software_version or '?'}, ICD {record.icd_version or '?'}, "
                     f"rig firmware {record.firmware_version or '?'}"),
        ("Model", model),
        ("Rig / clock", f"{'simulated rig' if record.simulated_rig else 'bench rig'}, {record.clock or '?'}"),
        ("Record", folder.name),
    ]


def draw_report(folder: Path, out_dir: Path | None = None) -> tuple[Path, Path]:
    """Draw the report of the record in ``folder``.

    Parameters
    ----------
    folder : pathlib.Path
        A record folder written by ``edc-bench test``.
    out_dir : pathlib.Path, optional
        Where to write (default: the record folder).

    Returns
    -------
    (pathlib.Path, pathlib.Path)
        The PDF and the PNG.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    folder = Path(folder)
    record = load_record(folder)
    trace = load_trace(folder)
    out_dir = Path(out_dir) if out_dir is not None else folder
    out_dir.mkdir(parents=True, exist_ok=True)

    fig = plt.figure(figsize=(8.27, 11.69))  # A4 portrait
    grid = fig.add_gridspec(24, 2, left=0.09, right=0.95, top=0.95, bottom=0.05, hspace=1.4, wspace=0.3)
    verdict = record.verdict
    fig.text(0.08, 0.965, "Solenoid valve diagnosis (edc-bench)", fontsize=15, weight="bold")
    fig.text(0.95, 0.965, f" {verdict} ", fontsize=15, weight="bold", color="white", ha="right",
             bbox={"facecolor": _VERDICT_COLOURS.get(verdict, "grey"), "edgecolor": "none", "pad": 4})

    ax_id = fig.add_subplot(grid[0:6, 0])
    ax_id.axis("off")
    for n, (key, value) in enumerate(_identity_lines(record, folder)):
        y = 1.0 - n * 0.1
        ax_id.text(0.0, y, key, fontsize=7.5, weight="bold", va="top", transform=ax_id.transAxes)
        # ids as typed: a '$' in them is no formula; wrapped here, as matplotlib's own wrapping measures text
        # with two '$' as a formula whatever parse_math says
        ax_id.text(0.34, y, textwrap.fill(value, _ID_COLUMN_CHARS, max_lines=2, placeholder=" ...",
                                          break_on_hyphens=False), fontsize=7.5,
                   va="top", transform=ax_id.transAxes, parse_math=False)

    ax_v = fig.add_subplot(grid[0:6, 1])
    ax_v.axis("off")
    _verdict_block(ax_v, record)

    ax_t = fig.add_subplot(grid[6:10, :])
    ax_t.axis("off")
    _parameter_table(ax_t, record)

    t = trace["t_s"]
    ax_track = fig.add_subplot(grid[11:14, 0])
    ax_error = fig.add_subplot(grid[14:16, 0])
    ax_conv = fig.add_subplot(grid[11:16, 1])
    ax_plane = fig.add_subplot(grid[17:24, :])
    if len(t):
        _tracking(ax_track, ax_error, trace)
        _convergence(ax_conv, trace, record)
    _decision_plane(ax_plane, record)

    pdf, png = out_dir / REPORT_PDF, out_dir / REPORT_PNG
    atomic_write(pdf, lambda f: fig.savefig(f, format="pdf"))
    atomic_write(png, lambda f: fig.savefig(f, format="png", dpi=110))
    plt.close(fig)
    return pdf, png


def _verdict_block(ax: Any, record: Record) -> None:
    cls = record.classification
    words = record.advice.words  # the technician's line, as the test's own output gives it
    lines = textwrap.wrap(words[:1].upper() + words[1:] + ".", 54)
    if cls is not None:
        rel = cls.features_rel
        lines += [
            f"P(faulty) = {cls.probability_faulty:.3f}",
            f"distance to the boundary {cls.distance:+.3f}",
            f"(marginal band +/- {cls.marginal_band or 0:g}; positive: worn side)",
            f"af {rel.get('af', math.nan) - 1:+.1%}, a1 {rel.get('a1', math.nan) - 1:+.1%} against a new valve",
        ]
    coil = record.coil
    if coil is not None and coil.resistance_20c_ohm is not None:
        low, high = coil.spec_ohm
        spec = f"<= {high:g}" if low is None else (f">= {low:g}" if high is None else f"{low:g}-{high:g}")
        lines.append(f"coil {coil.resistance_20c_ohm:.3f} ohm at 20 degC "
                     + ("(no spec)" if coil.in_spec is None else
                        f"(spec {spec}: {'in spec' if coil.in_spec else 'OUT OF SPEC'})"))
    baseline = record.baseline
    if baseline is not None and baseline.calibrated is False:
        lines += ["baseline NOMINAL: the variant is not calibrated; af and a1",
                  "were compared with data-sheet figures, not new valves:",
                  "this verdict may be wrong (edc-bench calibrate --append)"]
    elif baseline is not None:
        lines.append("baseline " + baseline_line(baseline.model_dump()).split(", station")[0])
    fit = record.identification.model_fit if record.identification is not None else None
    if fit is not None and fit.fits is False:  # what to do matters more than the figures, which the record holds
        lines += ["THE MODEL DOES NOT FIT THIS PUMP: a longer test will",
                  "not help. Check the variant is this pump's, the rack",
                  "moves freely, the solenoid's armature and wiring; a",
                  "pump like this needs its own variant (docs/faults.md)."]
        # each problem whole, wrapped to the block's width (record.json holds the figures with their limits)
        for problem in fit.problems[:3]:
            lines += textwrap.wrap(problem.split(" (limit")[0] + ";", 54)
    elif cls is None or (coil is not None and coil.in_spec is False):  # a classification's reasons repeat the above
        for reason in record.reasons:
            lines.append(reason if len(reason) < 60 else reason[:57] + "...")
    stop = record.stop
    if stop is not None and stop.time_s is not None:
        lines.append(f"ended after {stop.time_s:.1f} s of at most {stop.max_s or 0:g} s: {stop.reason}")
    for n, line in enumerate(lines):
        ax.text(0.0, 1.0 - n * 0.12, line, fontsize=8, va="top", transform=ax.transAxes,
                weight="bold" if n == 0 else "normal", parse_math=False)  # reasons quote ids and paths


def _parameter_table(ax: Any, record: Record) -> None:
    refs = _reference_values(record)
    rows = []
    for name in ("af", "a1", "a0", "a2", "b", "a3"):
        p = record.parameters.get(name)
        if p is None:
            continue
        value, std = p.value, p.std
        ref, source = refs.get(name, (math.nan, ""))
        change = f"{value / ref - 1:+.1%}" if value is not None and ref else ""
        rows.append([f"{name} ({_UNITS[name]})", f"{value:.5g}" if value is not None else "-",
                     f"{std:.2g}" if std is not None and p.estimated else "fixed",
                     f"{ref:.5g}" if math.isfinite(ref) else "-", source or "not recorded", change])
    if not rows:
        ax.text(0.0, 0.5, "No parameters: the test stopped before identifying any.", fontsize=9)
        return
    table = ax.table(cellText=rows, colLabels=["parameter", "identified", "+/- (1 sd)", "reference", "source",
                                               "change"], loc="center", cellLoc="center")
    table.auto_set_font_size(False)
    table.set_fontsize(8)
    table.scale(1.0, 1.3)
    ax.set_title("Identified parameters, referred to the reference coil (af, a1: the diagnosis features)",
                 fontsize=9, loc="left")


def _tracking(ax: Any, ax_error: Any, trace: dict[str, np.ndarray]) -> None:
    t = trace["t_s"]
    window = t >= max(t[-1] - 2.0, 0.0)
    ax.plot(t[window], trace["reference_mm"][window], "k--", lw=0.8, label="reference")
    ax.plot(t[window], trace["position_mm"][window], "C0", lw=0.8, label="rack")
    ax.set_title("Tracking, last 2 s (Fig. 3)", fontsize=9)
    ax.set_ylabel("rack (mm)", fontsize=8)
    ax.tick_params(labelsize=7)
    ax.legend(fontsize=7, loc="upper right")
    ax_error.plot(t, (trace["reference_mm"] - trace["position_mm"]) * 1e3, lw=0.4, color="C3")
    ax_error.set_ylabel("error (um)", fontsize=8)
    ax_error.set_xlabel("time (s), whole test", fontsize=8)
    ax_error.tick_params(labelsize=7)


def _convergence(ax: Any, trace: dict[str, np.ndarray], record: Record) -> None:
    t = trace["t_s"]
    refs = _reference_values(record)
    ceiling = 2.5
    for name, colour in (("af", "C1"), ("a1", "C2")):
        ref, source = refs.get(name, (math.nan, ""))
        if not (math.isfinite(ref) and ref):
            continue
        ratio = trace[f"{name}_hat"] / ref
        ceiling = max(ceiling, float(np.nanmax(ratio)) * 1.1)
        ax.plot(t, ratio, colour, lw=0.9, label=f"{name} / {source}, online")
        _period_fit_span(ax, record, name, ref, colour, float(t[-1]) if len(t) else math.nan)
    ax.axhline(1.0, color="grey", lw=0.6)
    start_s = record.identification.excitation_start_s if record.identification is not None else None
    if start_s is not None:
        ax.axvline(start_s, color="grey", lw=0.5, ls=":")
    ax.set_ylim(0.0, ceiling)
    ax.set_title("Convergence of af and a1 (Figs. 4-5)", fontsize=9)
    ax.set_xlabel("time (s)", fontsize=8)
    ax.set_ylabel("estimate / reference", fontsize=8)
    ax.tick_params(labelsize=7)
    ax.legend(fontsize=6.5, loc="lower right")  # the estimates sit at 1-2.5 once the excitation runs


def _period_fit_span(ax: Any, record: Record, name: str, ref: float, colour: str, end_s: float) -> None:
    """The period fit's value (the feature) over the whole periods it used, with its 2-sigma band."""
    param, ident = record.parameters.get(name), record.identification
    if param is None or ident is None:
        return
    value, std, periods, period_s = param.value, param.std, ident.periods, ident.period_s
    if value is None or std is None or not (periods and period_s and math.isfinite(end_s)):
        return
    start_s = max(0.0, end_s - periods * period_s)
    ax.hlines(value / ref, start_s, end_s, colors=colour, lw=2.2, linestyles="--",
              label=f"{name}, period fit over {periods} periods (the feature)")
    ax.fill_between([start_s, end_s], (value - 2 * std) / ref, (value + 2 * std) / ref, color=colour, alpha=0.2,
                    lw=0)


def boundary_distance(af_rel: np.ndarray, a1_rel: np.ndarray, p_faulty: np.ndarray, threshold: float) -> np.ndarray:
    """Signed distance of each grid point to the boundary (P = threshold), positive on the faulty side.

    The boundary is the threshold contour of the recorded P(faulty) grid;
    each point's distance is to the nearest point of that contour, as the
    classifier measures it (in relative-feature units).
    """
    import contourpy

    lines = contourpy.contour_generator(af_rel, a1_rel, p_faulty).lines(threshold)
    if not lines:
        return np.where(p_faulty >= threshold, np.inf, -np.inf)
    boundary = np.concatenate(lines)
    points = np.column_stack([af_rel.ravel(), a1_rel.ravel()])
    nearest = np.sqrt(((points[:, None, :] - boundary[None, :, :]) ** 2).sum(axis=2)).min(axis=1)
    return np.where(p_faulty.ravel() >= threshold, nearest, -nearest).reshape(p_faulty.shape)


def _decision_plane(ax: Any, record: Record) -> None:
    cls, plane = record.classification, record.decision_plane
    ax.set_title("Decision plane (Fig. 7): the valve against the boundary", fontsize=9)
    if cls is None or plane is None:
        ax.text(0.5, 0.5, "not classified" if not cls else "decision plane not in this record",
                ha="center", va="center", fontsize=10, transform=ax.transAxes)
        ax.set_xticks([])
        ax.set_yticks([])
        return
    p = np.asarray(plane.p_faulty, dtype=float)
    A, B = np.meshgrid(np.linspace(*plane.af_rel_range, p.shape[1]), np.linspace(*plane.a1_rel_range, p.shape[0]))
    dist = boundary_distance(A, B, p, plane.threshold)
    band = plane.marginal_band
    point = np.array([cls.features_rel.get("af", math.nan), cls.features_rel.get("a1", math.nan)])
    ax.contourf(A, B, dist, levels=[-np.inf, -band], colors=["#e8f5e9"])
    ax.contourf(A, B, dist, levels=[band, np.inf], colors=["#ffebee"])
    ax.contourf(A, B, dist, levels=[-band, band], colors=["0.85"])
    ax.contour(A, B, p, levels=[plane.threshold], colors="k", linewidths=1.2)
    ax.scatter([1.0], [1.0], marker="s", color="C0", s=40, label="new-valve baseline")
    ax.scatter([point[0]], [point[1]], marker="*", s=220, color=_VERDICT_COLOURS.get(cls.verdict, "k"),
               edgecolor="k", zorder=5, label=f"this valve: {cls.verdict}")
    ax.plot([], [], "k-", label="decision boundary")
    ax.fill([], [], color="0.85", label=f"marginal band +/- {band:g}")
    ax.set_xlabel("af / baseline", fontsize=8)
    ax.set_ylabel("a1 / baseline", fontsize=8)
    ax.tick_params(labelsize=7)
    ax.legend(fontsize=7, loc="upper left")
    ax.grid(alpha=0.3)
