"""One valve's trend as a figure: af's and a1's change per visit against a new valve, and the distance to the FAIL
limit with the marginal band (``history --trend --plot`` draws it to a PNG, the web view's valve page as SVG)."""

from __future__ import annotations

import functools
from typing import TYPE_CHECKING

from edc_bench.history.visits import Visit
from edc_bench.timefmt import local_text

if TYPE_CHECKING:
    from matplotlib.figure import Figure


@functools.lru_cache(maxsize=64)
def marginal_band(variant_name: str) -> float | None:
    """The marginal band of the model that judges ``variant_name``'s valves (None: a variant or model this station
    cannot load; the plot then draws the limit alone)."""
    try:
        from edc_bench.config import load_variant
        from edc_bench.verdict.classifier import default_classifier

        return float(default_classifier(variant=load_variant(variant_name)).marginal_band)
    except Exception:  # noqa: BLE001 - a plot without its band lines is still the trend
        return None


def trend_figure(shown: list[Visit], valve: str) -> Figure:
    """One point per visit (its deciding test's figures), marked with its decision, dated in local time: af's and
    a1's change, and below it the valve's distance to the FAIL limit with the marginal band around it."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from edc_bench.records.report_plots import VERDICT_COLOURS

    fig, (ax, limit_ax) = plt.subplots(2, 1, figsize=(7, 5.2), sharex=True, height_ratios=(3, 2))
    numbers = list(range(1, len(shown) + 1))
    colours = [VERDICT_COLOURS.get(v.decision, "0.5") for v in shown]
    for ratios, label, style in (([v.last.af_rel for v in shown], "af", "-"),
                                 ([v.last.a1_rel for v in shown], "a1", "--")):
        change_pct = [100 * ((ratio or float("nan")) - 1) for ratio in ratios]
        ax.plot(numbers, change_pct, style, color="0.4", lw=1.0, label=label)
        ax.scatter(numbers, change_pct, zorder=3, s=36, c=colours, marker="o" if label == "af" else "s")
    for n, visit in zip(numbers, shown, strict=True):
        ax.annotate(visit.decision, (n, 100 * ((visit.last.a1_rel or float("nan")) - 1)), fontsize=6,
                    textcoords="offset points", xytext=(0, 6), ha="center")
    ax.axhline(0.0, color="grey", lw=0.8)
    ax.margins(y=0.15)  # room for the decisions above the points
    ax.set_ylabel("change against\na new valve (%)")
    ax.set_title(f"valve {valve}", parse_math=False)  # the id as typed: '$' is not a formula here
    ax.legend()
    # the classifier's signed distance: 0 is the limit (FAIL beyond it), the band around it MARGINAL
    distances = [v.last.distance for v in shown]
    limit_ax.plot(numbers, [float("nan") if d is None else d for d in distances], "-", color="0.4", lw=1.0)
    limit_ax.scatter(numbers, [float("nan") if d is None else d for d in distances], zorder=3, s=36, c=colours)
    limit_ax.axhline(0.0, color=VERDICT_COLOURS.get("FAIL", "red"), lw=1.2, label="limit: FAIL above")
    band = marginal_band(str(shown[-1].last.variant or ""))
    if band is not None:
        limit_ax.axhspan(-band, band, color=VERDICT_COLOURS.get("MARGINAL", "orange"), alpha=0.25, lw=0,
                         label=f"marginal band (+/-{band:g})")
    limit_ax.set_ylabel("distance to\nthe limit")
    limit_ax.legend(fontsize=7, loc="best")
    limit_ax.set_xlabel("visit, local time (its decision above its points)")
    limit_ax.set_xticks(numbers, [local_text(v.first.started_at) for v in shown], rotation=30, fontsize=7,
                        ha="right")  # the date ends under its point, never past the figure's edge
    fig.tight_layout()
    return fig


def close(fig: Figure) -> None:
    """Release a figure :func:`trend_figure` made."""
    import matplotlib.pyplot as plt

    plt.close(fig)
