"""Estimators on synthetic data: convergence, uncertainty, robustness."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from edc_bench.control.estimators import NormalisedGradient, RecursiveLeastSquares

TRUE = np.array([0.5, -1.2, 2.0, 0.3])


def _data(n: int, noise: float, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    t = np.arange(n) * 1e-3
    w = np.column_stack([np.sin(2 * np.pi * 0.5 * t), np.cos(2 * np.pi * 3 * t), np.sign(np.sin(2 * np.pi * 0.5 * t)),
                         np.ones(n)])
    return w, w @ TRUE + rng.normal(0, noise, n)


def test_rls_recovers_parameters_and_their_uncertainty() -> None:
    w, y = _data(20000, 0.01)
    rls = RecursiveLeastSquares([0.0] * 4, [10.0] * 4, 0.9995)
    for row, target in zip(w, y, strict=True):
        rls.update(row.tolist(), float(target))
    assert rls.theta == pytest.approx(TRUE.tolist(), abs=3e-3)
    std = rls.std()
    assert all(0 < s < 3e-3 for s in std)
    assert math.sqrt(rls.residual_var) == pytest.approx(0.01, rel=0.1)


def test_gradient_converges_with_per_parameter_gains() -> None:
    w, y = _data(60000, 0.0)
    grad = NormalisedGradient([0.0] * 4, [20.0, 20.0, 20.0, 20.0], 1e-3)
    for row, target in zip(w, y, strict=True):
        grad.update(row.tolist(), float(target))
    assert grad.theta == pytest.approx(TRUE.tolist(), abs=1e-2)


def test_non_finite_samples_are_refused() -> None:
    rls = RecursiveLeastSquares([0.0, 0.0], [1.0, 1.0], 0.999)
    assert rls.update([1.0, math.nan], 1.0) == 0.0
    assert rls.update([1.0, 1.0], math.inf) == 0.0
    assert rls.rejected == 2 and rls.updates == 0
    assert rls.theta == [0.0, 0.0]


finite = st.floats(min_value=-1e6, max_value=1e6, allow_nan=False, allow_infinity=False)


@settings(max_examples=200, deadline=None)
@given(st.lists(st.tuples(finite, finite, finite), min_size=1, max_size=200))
def test_estimates_stay_finite_for_any_finite_input(samples: list[tuple[float, float, float]]) -> None:
    rls = RecursiveLeastSquares([0.0, 0.0], [1.0, 1.0], 0.999)
    grad = NormalisedGradient([0.0, 0.0], [5.0, 5.0], 1e-3)
    for w0, w1, y in samples:
        rls.update([w0, w1], y)
        grad.update([w0, w1], y)
    assert all(math.isfinite(v) for v in rls.theta + grad.theta)
    assert all(math.isfinite(v) for row in rls.P for v in row)
