"""How well a run kept its tick deadlines, from its trace."""

from __future__ import annotations

import math

import numpy as np


def timing_summary(trace: dict[str, np.ndarray], period_s: float) -> dict[str, float]:
    """Lateness percentiles (us) of the ticks that ran, and how many started more than a period late
    (``ticks_late``; ticks lost to a host stall have no lateness: the loop's ``ticks_lost`` counts them)."""
    late = trace["lateness_s"]
    late = late[~np.isnan(late)]
    if len(late) == 0:  # the same keys, so a record's timing always reads the same way
        return {"ticks": 0, "lateness_p50_us": math.nan, "lateness_p99_us": math.nan, "lateness_p999_us": math.nan,
                "lateness_max_us": math.nan, "ticks_late": 0}
    q = np.percentile(late, [50, 99, 99.9]) * 1e6
    return {
        "ticks": int(len(late)),
        "lateness_p50_us": float(q[0]),
        "lateness_p99_us": float(q[1]),
        "lateness_p999_us": float(q[2]),
        "lateness_max_us": float(late.max() * 1e6),
        "ticks_late": int((late > period_s).sum()),  # started more than a period late
    }
