"""The report's plots, drawn from the record and its trace: the valve against the boundary (page 1), the estimates'
convergence and the tracking error (page 2).

Each function draws into axes the page has placed; the page draws the
title, so that it is fitted like every other text.
"""

from __future__ import annotations

import math

import numpy as np
from matplotlib.axes import Axes
from matplotlib.lines import Line2D
from matplotlib.patches import Patch

from edc_bench.records.report_content import pair_decision
from edc_bench.records.schema import Record
from edc_bench.section import FeaturePair
from edc_bench.verdict.verdicts import Verdict

VERDICT_COLOURS = {Verdict.PASS: "#2e7d32", Verdict.MARGINAL: "#f9a825", Verdict.FAIL: "#c62828",
                   Verdict.INVALID: "#6a1b9a"}
TICK_PT, LABEL_PT, LEGEND_PT = 7.0, 8.0, 7.0
_REGION_COLOURS = {"pass": "#e8f5e9", "band": "0.85", "fail": "#ffebee"}


def reference_values(record: Record) -> dict[str, tuple[float, str]]:
    """Per parameter: the value it is compared with, and where that comes from, as the test recorded them."""
    return {name: (entry.value, entry.source) for name, entry in record.reference_values.items()
            if entry.value is not None}


def _style(ax: Axes, xlabel: str, ylabel: str) -> None:
    ax.set_xlabel(xlabel, fontsize=LABEL_PT)
    ax.set_ylabel(ylabel, fontsize=LABEL_PT)
    ax.tick_params(labelsize=TICK_PT)
    ax.grid(alpha=0.3)


def no_data(ax: Axes, message: str) -> None:
    """An empty frame saying why there is nothing to plot."""
    ax.set_xticks([])
    ax.set_yticks([])
    ax.text(0.5, 0.5, message, ha="center", va="center", fontsize=9, transform=ax.transAxes, parse_math=False)


def draw_decision(ax: Axes, record: Record) -> list[tuple[object, str]]:
    """The valve's friction and damping against the boundary between reusable and worn valves.

    Returns the legend's entries (handle, words) for the page to place
    beside the plot; none when the test was not classified.
    """
    cls, plane = record.classification, record.decision_plane
    if cls is None or plane is None:
        no_data(ax, "Not judged: no comparison to show" if cls is None
                else "This record holds no decision plane")
        return []
    p = np.asarray(plane.p_faulty, dtype=float)
    af_grid, a1_grid = np.meshgrid(np.linspace(*plane.af_rel_range, p.shape[1]),
                                   np.linspace(*plane.a1_rel_range, p.shape[0]))
    dist = boundary_distance(af_grid, a1_grid, p, plane.threshold)
    band = plane.marginal_band
    ax.contourf(af_grid, a1_grid, dist, levels=[-np.inf, -band], colors=[_REGION_COLOURS["pass"]])
    ax.contourf(af_grid, a1_grid, dist, levels=[band, np.inf], colors=[_REGION_COLOURS["fail"]])
    ax.contourf(af_grid, a1_grid, dist, levels=[-band, band], colors=[_REGION_COLOURS["band"]])
    ax.contour(af_grid, a1_grid, p, levels=[plane.threshold], colors="k", linewidths=1.2)
    nominal = record.baseline is not None and record.baseline.calibrated is False
    pair = pair_decision(record)  # one decision everywhere: the chart of a retest pair names it
    (new,) = ax.plot([1.0], [1.0], "s", color="C0", ms=7)
    star = _valve_point(ax, cls.features_rel, plane.af_rel_range, plane.a1_rel_range,
                        VERDICT_COLOURS.get(cls.verdict, "k"))
    _style(ax, "friction (af), relative to a new valve", "damping (a1), relative to a new valve")
    entries: list[tuple[object, str]] = [
        (star, f"this valve: {cls.verdict}" + (f" (tested twice: {pair})" if pair else "")),
        (new, "new valve (data sheet)" if nominal else "new valve (average)"),
        (Line2D([], [], color="k", lw=1.2), "limit between reusable and worn"),
        (Patch(color=_REGION_COLOURS["pass"]), "PASS: reusable"),
        (Patch(color=_REGION_COLOURS["band"]), "MARGINAL: near the limit, retest"),
        (Patch(color=_REGION_COLOURS["fail"]), "FAIL: worn, replace"),
    ]
    return entries


def _valve_point(ax: Axes, features_rel: FeaturePair, af_range: tuple[float, float],
                 a1_range: tuple[float, float], colour: str) -> object:
    """The valve's star; a valve beyond the chart is drawn at its edge, pointing the way it lies."""
    af, a1 = features_rel.numbers()
    shown_af, shown_a1 = float(np.clip(af, *af_range)), float(np.clip(a1, *a1_range))
    beyond = math.isfinite(af) and math.isfinite(a1) and (shown_af, shown_a1) != (af, a1)
    (star,) = ax.plot([shown_af], [shown_a1], "*", ms=17, color=colour, mec="k", zorder=5, clip_on=False)
    if beyond:
        right, top = shown_af > sum(af_range) / 2, shown_a1 > sum(a1_range) / 2  # the words towards the middle
        ax.annotate(f"beyond the chart: af \u00d7{af:.2f}, a1 \u00d7{a1:.2f}", (shown_af, shown_a1),
                    xytext=(-10 if right else 10, -10 if top else 10), textcoords="offset points",
                    ha="right" if right else "left", va="top" if top else "bottom", fontsize=LEGEND_PT,
                    annotation_clip=False)
    ax.set_xlim(*af_range)
    ax.set_ylim(*a1_range)
    return star


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


def draw_convergence(ax: Axes, trace: dict[str, np.ndarray], record: Record) -> None:
    """The online estimates of af and a1 over the test, and the period fit's value the verdict comes from."""
    t = trace["t_s"]
    if not len(t):
        no_data(ax, "no samples recorded")
        return
    refs = reference_values(record)
    ceiling = 2.5
    for name, colour in (("af", "C1"), ("a1", "C2")):
        ref, source = refs.get(name, (math.nan, ""))
        if not (math.isfinite(ref) and ref):
            continue
        ratio = trace[f"{name}_hat"] / ref
        finite = ratio[np.isfinite(ratio)]
        ceiling = max(ceiling, float(finite.max()) * 1.1) if finite.size else ceiling
        ax.plot(t, ratio, colour, lw=0.9, label=f"{name} / {source}, online")
        _period_fit_span(ax, record, name, ref, colour, float(t[-1]))
    ax.axhline(1.0, color="grey", lw=0.6)
    start_s = record.identification.excitation_start_s if record.identification is not None else None
    if start_s is not None:
        ax.axvline(start_s, color="grey", lw=0.5, ls=":")
    ax.set_ylim(0.0, ceiling)
    ax.set_xlim(float(t[0]), float(t[-1]))
    _style(ax, "time (s)", "estimate / reference")
    if ax.get_legend_handles_labels()[0]:
        ax.legend(fontsize=6.5, loc="best")  # lower right on a pump the model fits: the estimates sit at 1-2.5


def _period_fit_span(ax: Axes, record: Record, name: str, ref: float, colour: str, end_s: float) -> None:
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


def draw_tracking_error(ax: Axes, trace: dict[str, np.ndarray]) -> None:
    """The command minus the rack position over the whole test."""
    t = trace["t_s"]
    if not len(t):
        no_data(ax, "no samples recorded")
        return
    ax.plot(t, (trace["reference_mm"] - trace["position_mm"]) * 1e3, lw=0.4, color="C3")
    ax.set_xlim(float(t[0]), float(t[-1]))
    _style(ax, "time (s)", "command \u2212 rack (\u00b5m)")
