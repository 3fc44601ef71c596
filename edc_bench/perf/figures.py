"""One measured figure, its reference and its target; percentiles of timing samples."""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

import numpy as np


@dataclass
class Figure:
    """A measured figure beside what it is compared with.

    Attributes
    ----------
    group : str
        One of the benchmark groups (:data:`edc_bench.perf.GROUPS`).
    name : str
        What was measured.
    value : float
        The measurement, in ``unit``.
    unit : str
        Unit of ``value`` and ``reference``.
    reference : float or None
        The figure it should approach (a floor measured in the same run), if any.
    reference_name : str
        What the reference is.
    target : str
        The target, in words (empty if none).
    met : bool or None
        Whether the target is met (None where there is no target).
    note : str
        Context: sample counts, CPU steal, why a target was missed.
    """

    group: str
    name: str
    value: float
    unit: str
    reference: float | None = None
    reference_name: str = ""
    target: str = ""
    met: bool | None = None
    note: str = ""

    def as_dict(self) -> dict[str, Any]:
        """Plain data for JSON."""
        return asdict(self)


@dataclass(frozen=True)
class SessionLatency:
    """The session app's latencies over a shift on the simulated rig (s): (median, worst) from a test's safe stop
    to its decision on screen, and to its reports drawn; the valves and the tests they took."""

    decision_s: tuple[float, float]
    report_s: tuple[float, float]
    valves: int
    tests: int


def percentiles(samples: np.ndarray | list[float], qs: tuple[float, ...] = (50, 99)) -> list[float]:
    """Percentiles ``qs`` of ``samples`` (NaN where there are none)."""
    values = np.asarray(samples, dtype=float)
    values = values[np.isfinite(values)]
    if len(values) == 0:
        return [float("nan")] * len(qs)
    return [float(v) for v in np.percentile(values, qs)]
