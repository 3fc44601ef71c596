"""Report figure in the style of the paper's Figs. 3-5: parameter convergence
panels and the rack tracking its reference."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np


def draw_report_figure(path: Path, trace: dict[str, np.ndarray], title: str,
                       truth: dict[str, float] | None = None, excitation_start_s: float = 0.0) -> None:
    """Draw and save the figure (PNG).

    Parameters
    ----------
    path : pathlib.Path
        Output PNG path (written atomically).
    trace : dict of numpy.ndarray
        The test's trace columns.
    title : str
        Figure title (variant, valve, verdict).
    truth : dict, optional
        True parameter values (simulated rig) drawn as dashed lines.
    excitation_start_s : float
        Marks where the excitation (and the estimation) starts.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from edc_bench.paths import atomic_write

    t = trace["t_s"]
    fig, axes = plt.subplots(4, 1, figsize=(8.3, 10.5), sharex=True, constrained_layout=True)
    fig.suptitle(title, parse_math=False)  # ids as typed: a '$' in them is no formula
    panels: list[tuple[Any, list[tuple[str, str]], str]] = [
        (axes[0], [("af_hat", "$\\hat a_f$"), ("b_hat", "$\\hat b$ / 10")], "V"),
        (axes[1], [("a1_hat", "$\\hat a_1$"), ("a2_hat", "$\\hat a_2$ x 10")], "V s/mm, V s$^2$/mm"),
        (axes[2], [("a0_hat", "$\\hat a_0$")], "V/mm"),
    ]
    scale = {"b_hat": 0.1, "a2_hat": 10.0}
    # these are the estimates that drive the feedforward; the verdict rests on the fit over whole periods
    axes[0].set_title("online estimates (the verdict's figures: the period fit, in report.pdf)", fontsize=9)
    for ax, series, unit in panels:
        for column, label in series:
            k = scale.get(column, 1.0)
            (line,) = ax.plot(t, trace[column] * k, label=label, linewidth=1.2)
            name = column.removesuffix("_hat")
            if truth and name in truth:
                ax.axhline(truth[name] * k, color=line.get_color(), linestyle="--", linewidth=0.8,
                           label=f"{label} true")
        ax.set_ylabel(unit)
        ax.axvline(excitation_start_s, color="0.6", linewidth=0.8,
                   label="excitation starts" if ax is axes[0] else None)
        ax.legend(loc="lower right", fontsize=8, ncol=2)
        ax.grid(alpha=0.3)
    ax = axes[3]
    ax.plot(t, trace["reference_mm"], linestyle=":", color="k", label="reference", linewidth=1.0)
    ax.plot(t, trace["position_mm"], color="C3", label="rack (LVDT)", linewidth=1.0)
    ax.set_ylabel("rack position, mm")
    ax.set_xlabel("time, s")
    ax.legend(loc="lower right", fontsize=8)
    ax.grid(alpha=0.3)
    atomic_write(path, lambda f: fig.savefig(f, format="png", dpi=110))
    plt.close(fig)
