"""Property-based checks (hypothesis) on the pure parts that face the outside world."""

from __future__ import annotations

import math

from hypothesis import given, settings
from hypothesis import strategies as st

from edc_bench.config import load_variant
from edc_bench.control.design import build_controller

VARIANT = load_variant()
LIMIT = VARIANT.rig.drive_limit_v
finite = st.floats(min_value=-1e9, max_value=1e9, allow_nan=False, allow_infinity=False)


@settings(max_examples=200, deadline=None)
@given(st.floats(min_value=-5.0, max_value=30.0), st.lists(st.tuples(st.integers(0, 40_000), finite),
                                                            min_size=1, max_size=60))
def test_drive_stays_finite_and_within_limits_for_any_finite_input(start_mm: float, ticks) -> None:
    controller = build_controller(VARIANT, start_mm)
    for k, measured_mm in sorted(ticks):
        u = controller.step(k, measured_mm)
        assert math.isfinite(u) and -LIMIT <= u <= LIMIT
        assert all(math.isfinite(p) for p in controller.parameters())
