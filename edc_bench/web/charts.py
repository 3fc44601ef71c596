"""The web view's charts: matplotlib figures as SVG data, shown as images (no script, nothing from another host)."""

from __future__ import annotations

import base64
import contextlib
import datetime as dt
import io
import threading
from collections.abc import Iterator
from typing import TYPE_CHECKING, Any

from edc_bench.timefmt import parse_stored

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from edc_bench.history.summary import DayCount
    from edc_bench.history.visits import Visit
    from edc_bench.web.views import FigureDrift


def svg_data(fig: Figure, tight: bool = True) -> str:
    """A figure as a ``data:`` URL of its SVG (an ``<img>`` shows it; the CSP allows images from data: only);
    ``tight``: cropped to what is drawn (matplotlib draws it twice to know), else as the figure's margins lay it out."""
    import matplotlib.pyplot as plt

    buffer = io.BytesIO()
    fig.savefig(buffer, format="svg", **({"bbox_inches": "tight"} if tight else {}))
    plt.close(fig)
    return "data:image/svg+xml;base64," + base64.b64encode(buffer.getvalue()).decode("ascii")


#: a station's name in a chart's legend is cut after this many characters (the legend's room is fixed)
LEGEND_CHARACTERS = 24

#: names are the shops' text: '$' in a station's name is no formula
_AS_TYPED = {"text.parse_math": False}
#: pyplot and its settings are global: the server's threads draw one chart at a time
_DRAWING = threading.Lock()


@contextlib.contextmanager
def drawing() -> Iterator[None]:
    """Hold the drawing lock (matplotlib's pyplot and rc settings are global: one drawing at a time)."""
    with _DRAWING:
        yield


def _pyplot():  # noqa: ANN202 - matplotlib's pyplot, on the headless backend
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def warm() -> None:
    """Load the plotting library and draw one small chart (what the first page drawn would otherwise pay)."""
    from edc_bench.history.summary import DayCount

    tests_per_day((DayCount("2026-01-01", "warm", 1),))


def tests_per_day(days: tuple[DayCount, ...], top: int = 8, period: str = "day") -> str | None:
    """Tests per day (or ``month``), a bar per period stacked by station (the ``top`` busiest stations, the rest as
    'others')."""
    if not days:
        return None
    plt = _pyplot()
    with _DRAWING, plt.rc_context(_AS_TYPED):
        return _tests_per_day(plt, days, top, period)


def _tests_per_day(plt: Any, days: tuple[DayCount, ...], top: int, period: str) -> str:
    totals: dict[str, int] = {}
    for d in days:
        totals[d.station] = totals.get(d.station, 0) + d.tests
    named = sorted(totals, key=lambda s: (-totals[s], s))[:top]
    dates = sorted({d.day for d in days})
    index = {day: k for k, day in enumerate(dates)}
    series: dict[str, list[int]] = {name: [0] * len(dates) for name in [*named, "others"]}
    for d in days:
        series[d.station if d.station in named else "others"][index[d.day]] += d.tests
    fig, ax = plt.subplots(figsize=(8, 3.2))
    x = [dt.date.fromisoformat(day if len(day) == 10 else f"{day}-01") for day in dates]
    shown = {name: counts for name, counts in series.items() if any(counts)}
    # one filled step outline per station, not a patch per bar: a year of a hundred stations draws as fast as a week
    ax.stackplot(x, *shown.values(), labels=_cut_apart(list(shown)), step="mid")
    ax.set_ylabel(f"tests per {period}")
    ax.set_xlabel(f"{period} (UTC)")
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))  # beside the days, never over them
    fig.autofmt_xdate()
    # margins set, not measured: cropping to what is drawn draws the chart twice (a quarter of the chain page's
    # time); the legend's names are cut to fit its room
    fig.subplots_adjust(left=0.1, right=0.76, bottom=0.3, top=0.96)
    return svg_data(fig, tight=False)


def _cut(name: str) -> str:
    return name if len(name) <= LEGEND_CHARACTERS else name[:LEGEND_CHARACTERS - 1] + "\u2026"


def _cut_apart(names: list[str]) -> list[str]:
    """Each name cut to the legend's room; names that would read alike are numbered (#2, #3) in their order."""
    labels, seen = [], {}
    for name in names:
        label = _cut(name)
        seen[label] = seen.get(label, 0) + 1
        labels.append(label if seen[label] == 1 else f"{label[:LEGEND_CHARACTERS - 3]}#{seen[label]}")
    return labels


def drift_chart(station: str, drifts: list[FigureDrift]) -> str | None:
    """A station's self-checks as a control chart: each figure's drift against its registration, in units of its
    tolerance (the limits at +/-1), the trend's straight line drawn on to where it crosses a limit."""
    shown = [d for d in drifts if d.points]
    if not shown:
        return None
    plt = _pyplot()
    with _DRAWING, plt.rc_context(_AS_TYPED):
        return _drift_chart(plt, station, shown)


def valve_trend(shown: list[Visit], valve_id: str) -> str:
    """A valve's wear trend (:func:`edc_bench.history.trend_plot.trend_figure`) as SVG data."""
    from edc_bench.history.trend_plot import trend_figure

    with _DRAWING:
        return svg_data(trend_figure(shown, valve_id))


def _drift_chart(plt: Any, station: str, shown: list[FigureDrift]) -> str:
    fig, ax = plt.subplots(figsize=(8, 3.2))
    for drift in shown:
        times = [parse_stored(when) for when, _ in drift.points]
        line, = ax.plot(times, [value for _, value in drift.points], "o-", ms=3, lw=1, label=drift.label)
        if drift.crossing_at is not None and drift.slope_per_day is not None:
            end = parse_stored(drift.crossing_at)
            ax.plot([times[-1], end], [drift.points[-1][1], drift.limit_sign], ":", color=line.get_color(), lw=1)
    for limit in (-1.0, 1.0):
        ax.axhline(limit, color="#b00020", lw=1.2)
    ax.axhline(0.0, color="grey", lw=0.6)
    ax.set_ylabel("drift / tolerance")
    ax.set_title(f"station {station}: self-checks against the reference valve", parse_math=False, fontsize=9)
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    fig.autofmt_xdate()
    return svg_data(fig)
