"""Student's t quantiles without SciPy: SciPy's figures, for every degree of freedom the early stop can use."""

from __future__ import annotations

import pytest
from scipy.special import stdtrit

from edc_bench.identification.student_t import t_quantile


@pytest.mark.parametrize("q", [0.5 + 0.99 / 2, 0.5 + 0.95 / 2, 0.5 + 0.999 / 2, 0.9, 0.6])
def test_quantiles_are_scipys(q: float) -> None:
    for nu in range(1, 301):
        assert t_quantile(q, nu) == pytest.approx(float(stdtrit(nu, q)), rel=1e-12, abs=0.0), nu


def test_out_of_range_is_refused() -> None:
    for q, nu in ((0.5, 3), (1.0, 3), (0.99, 0)):
        with pytest.raises(ValueError, match="t_quantile needs"):
            t_quantile(q, nu)
