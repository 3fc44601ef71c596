"""The figures of docs/faults.md, "The rig self-check": each figure's spread on the simulated rig, the tolerances set
from it, and what a self-check says of each drift.

:func:`selfcheck_spread` (measurement ``faults-selfcheck-spread``) measures the reference valve (a new one) on the
simulated rig of each shipped test variant with different noise seeds, and keeps each figure's standard deviation
and its largest change from the seed-0 run (the registration): what a self-check sees from noise alone.
:func:`selfcheck_drifts` (``faults-selfcheck-drifts``) registers on ``p-edc-default`` with seed 0 and checks with
seed 3, on a rig without drift and with each drift of :data:`DRIFTS`: the verdict line and the figures beyond their
tolerance.
"""

from __future__ import annotations

from typing import Any

from figures.common import measurement, stored, table

#: The shipped variants the spread is measured on, and how many noise seeds each.
SPREAD_RUNS = {"p-edc-default": 20, "p-edc-long": 10, "p-edc-hard": 10}
#: A tolerance must be at least this many times the largest change noise alone gave.
MARGIN = 5.0
#: The drifts shown: none, the two the self-check must catch, then the others the simulated rig can have.
DRIFTS = ("none", "lvdt_offset_mm=0.05", "current_gain=1.03", "lvdt_gain=1.03", "current_offset_a=0.02",
          "lvdt_offset_mm=-0.05")
#: The figures in the page's words, and the unit of their change.
NAMES = {"lvdt_zero_mm": ("LVDT zero (rest position)", "mm"), "current_zero_a": ("current zero (rest current)", "A"),
         "coil_r20_ohm": ("coil resistance at 20 degC", "%"), "a0_v_per_mm": ("spring rate a0", "%"),
         "af_v": ("friction af", "%"), "a1_v_s_per_mm": ("damping a1", "%")}


@measurement("faults-selfcheck-spread", minutes=1.5)
def selfcheck_spread() -> dict[str, Any]:
    """Each figure's spread over noise seeds on each test variant (change: absolute for the zeros, else relative)."""
    import numpy as np

    from edc_bench.config import load_variant
    from edc_bench.selfcheck.compare import QUANTITIES, REST_QUANTITIES
    from edc_bench.selfcheck.measure import measure_simulated

    out: dict[str, Any] = {}
    for name, runs in SPREAD_RUNS.items():
        variant = load_variant(name)
        values = [measure_simulated(variant, "new", seed)[0] for seed in range(runs)]
        if any(v.test_problems for v in values):
            raise RuntimeError(f"a reference test on {name} was not trustworthy")
        figures = {}
        for q in QUANTITIES:
            x = np.array([getattr(v, q) for v in values])
            change = x - x[0] if q in REST_QUANTITIES else x / x[0] - 1.0
            spread = np.std(x, ddof=1) if q in REST_QUANTITIES else np.std(x, ddof=1) / abs(np.mean(x))
            figures[q] = {"sd": round(float(spread), 7), "max_change": round(float(np.abs(change).max()), 7)}
        out[name] = {"runs": runs, "figures": figures}
    return out


@measurement("faults-selfcheck-drifts", minutes=0.3)
def selfcheck_drifts() -> list[dict[str, Any]]:
    """A registration (seed 0) and a check (seed 3) on ``p-edc-default`` for each drift of :data:`DRIFTS`."""
    from edc_bench.config import load_variant
    from edc_bench.selfcheck import Registration, Rig, run_selfcheck
    from edc_bench.selfcheck.measure import measure_simulated
    from edc_bench.sim.drift import parse_rig_drift

    variant = load_variant("p-edc-default")
    values, _ = measure_simulated(variant, "new", 0)
    registration = Registration(1, "bench1", "REF-1", variant.name, values, simulated=True, valve_spec="new", seed=0)
    out = []
    for drift in DRIFTS:
        result = run_selfcheck(Rig(drift=parse_rig_drift(drift)), registration, variant, seed=3).result
        out.append({"drift": drift, "line": result.line(), "causes": [str(c) for c in result.causes],
                    "drifted": list(result.drifted),
                    "changes": {q.name: round(q.drift, 5) for q in result.quantities}})
    return out


def _change(value: float, unit: str) -> str:
    return f"{value * 100:.3f} %" if unit == "%" else (f"{value:.4f} mm" if unit == "mm" else f"{value:.4f} A")


def _limit(value: float, unit: str) -> str:
    return f"{value * 100:g} %" if unit == "%" else f"{value:g} {unit}"


def spread_table() -> str:
    """Each figure: its spread and largest change by variant, the tolerance, and the margin; checks the rule."""
    from edc_bench.config import load_variant
    from edc_bench.selfcheck import tolerances_of

    data = stored("faults-selfcheck-spread")
    rows = []
    for q, (label, unit) in NAMES.items():
        cells, worst = [], 0.0
        for name in SPREAD_RUNS:
            f = data[name]["figures"][q]
            cells.append(f"{_change(f['sd'], unit)} / {_change(f['max_change'], unit)}")
            worst = max(worst, f["max_change"])
        tolerance = {tolerances_of(load_variant(name)).of(q) for name in SPREAD_RUNS}
        if len(tolerance) != 1:
            raise RuntimeError(f"the test variants' tolerances of {q} differ: {tolerance}")
        limit = tolerance.pop()
        if limit < MARGIN * worst:
            raise RuntimeError(f"the tolerance of {q} ({limit}) is less than {MARGIN:g} times the largest change "
                               f"noise gave ({worst}): widen it")
        margin = f"{limit / worst:.0f}x" if worst > 0 else "no change seen"
        rows.append((label, *cells, _limit(limit, unit), margin))
    header = ("figure", *(f"`{name}` ({data[name]['runs']} seeds): sd / largest change" for name in SPREAD_RUNS),
              "tolerance", "tolerance / largest change")
    return table(header, rows)


def drifts_table() -> str:
    """Each drift of the simulated rig, and what the self-check says (checks that each is caught alone)."""
    expected = {"none": [], "lvdt_offset_mm=0.05": ["lvdt_zero_mm"], "current_gain=1.03": ["coil_r20_ohm"],
                "lvdt_gain=1.03": ["a0_v_per_mm", "a1_v_s_per_mm"], "current_offset_a=0.02": ["current_zero_a"],
                "lvdt_offset_mm=-0.05": ["lvdt_zero_mm"]}
    rows = []
    for run in stored("faults-selfcheck-drifts"):
        if run["drifted"] != expected[run["drift"]]:
            raise RuntimeError(f"--rig-drift {run['drift']}: the self-check named {run['drifted']}, not "
                               f"{expected[run['drift']]}")
        rows.append((f"`{run['drift']}`", ", ".join(NAMES[q][0] for q in run["drifted"]) or "-",
                     f"`{run['line']}`"))
    return table(("`--rig-drift`", "figures beyond their tolerance", "what the self-check says"), rows)
