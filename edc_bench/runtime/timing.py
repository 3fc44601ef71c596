"""How well a run kept its tick deadlines, from its trace."""

from __future__ import annotations

import math

import numpy as np


def timing_summary(trace: dict[str, np.ndarray], period_s: float) -> dict[str, float]:
    """Lateness percentiles (us) and overrun count of the ticks that ran (ticks lost to a host stall have none)."""
    late = trace["lateness_s"]
    late = late[~np.isnan(late)]
    if len(late) == 0:  # the same keys, so a record's timing always reads the same way
        return {"ticks": 0, "lateness_p50_us": math.nan, "lateness_p99_us": math.nan, "lateness_p999_us": math.nan,
                "lateness_max_us": math.nan, "overruns": 0}
    q = np.percentile(late, [50, 99, 99.9]) * 1e6
    return {
        "ticks": int(len(late)),
        "lateness_p50_us": float(q[0]),
        "lateness_p99_us": float(q[1]),
        "lateness_p999_us": float(q[2]),
        "lateness_max_us": float(late.max() * 1e6),
        "overruns": int((late > period_s).sum()),
    }
