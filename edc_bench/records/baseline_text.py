"""How a record's baseline is told to a person (panel, plain report, report page).

Reads only the record's ``baseline`` dict, so the report needs nothing from the diagnosis.
"""

from __future__ import annotations

import math
from typing import Any


def baseline_line(baseline: dict[str, Any] | None) -> str:
    """One line: measured or NOMINAL, the figures' uncertainty, where and when they were measured."""
    if not baseline:
        return "no baseline used (the test was not judged)"
    if baseline.get("calibrated") is False:
        return ("NOMINAL baseline: the variant is not calibrated, af and a1 were compared with figures from its "
                "data sheet, not measured on new valves")
    tests = baseline.get("tests", 0)
    af_u, a1_u = baseline.get("af_uncertainty_v"), baseline.get("a1_uncertainty_v_s_per_mm")
    if isinstance(af_u, float) and math.isfinite(af_u) and isinstance(a1_u, float) and math.isfinite(a1_u):
        spread = f"+/- {af_u / baseline['af_v']:.2%} in af, {a1_u / baseline['a1_v_s_per_mm']:.2%} in a1"
    else:
        spread = "uncertainty not stated"
    when = f", {str(baseline['written_at'])[:10]}" if baseline.get("written_at") else ""
    where = f", station {baseline['station']}" if baseline.get("station") else ""
    return f"measured on {tests} new-valve tests ({spread}), {baseline.get('source', '')}{when}{where}"
