"""How a record's baseline is told to a person (panel, plain report, report page).

Reads only the record's ``baseline`` section, so the report needs nothing from the diagnosis.
"""

from __future__ import annotations

import math

from edc_bench.records.schema import BaselineSummary


def baseline_line(baseline: BaselineSummary | None) -> str:
    """One line: measured or NOMINAL, the figures' uncertainty, where and when they were measured."""
    if baseline is None:
        return "no baseline used (the test was not judged)"
    if baseline.calibrated is False:
        return ("NOMINAL baseline: the variant is not calibrated, af and a1 were compared with figures from its "
                "data sheet, not measured on new valves")
    tests = baseline.tests
    af_u, a1_u = baseline.af_uncertainty_v, baseline.a1_uncertainty_v_s_per_mm
    if af_u is not None and math.isfinite(af_u) and a1_u is not None and math.isfinite(a1_u) \
            and baseline.af_v and baseline.a1_v_s_per_mm:
        spread = f"+/- {af_u / baseline.af_v:.2%} in af, {a1_u / baseline.a1_v_s_per_mm:.2%} in a1"
    else:
        spread = "uncertainty not stated"
    when = f", {str(baseline.written_at)[:10]}" if baseline.written_at else ""
    where = f", station {baseline.station}" if baseline.station else ""
    return f"measured on {tests} new-valve tests ({spread}), {baseline.source}{when}{where}"
