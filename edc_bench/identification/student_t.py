"""Student's t quantiles for whole degrees of freedom, in the standard library alone.

The early stop's interval needs the t quantile for 1, 2, ... degrees of
freedom (the excitation periods measured, less one) before a test's first
tick. scipy.special's ``stdtrit`` gives them, but importing SciPy made the
test's start noticeably longer; for whole degrees of freedom the
distribution function has a closed form (Abramowitz and Stegun 26.7.3-4,
in the angle theta = atan(t / sqrt(nu))), which Newton's method inverts
(a test holds it within 1e-12 of SciPy's figures: a few units in the last
place for the early stop's confidences).
"""

from __future__ import annotations

import math
from statistics import NormalDist


def _central_probability(theta: float, nu: int) -> float:
    """P(|T| <= sqrt(nu) tan(theta)) for ``nu`` degrees of freedom."""
    s, c = math.sin(theta), math.cos(theta)
    c2 = c * c
    if nu % 2:  # odd: 2/pi (theta + sin cos (1 + 2/3 cos^2 + 2 4/(3 5) cos^4 + ...))
        term = total = 1.0
        for k in range(1, (nu - 1) // 2):
            term *= c2 * (2 * k) / (2 * k + 1)
            total += term
        return 2.0 / math.pi * (theta + (s * c * total if nu > 1 else 0.0))
    term = total = 1.0  # even: sin (1 + 1/2 cos^2 + 1 3/(2 4) cos^4 + ...)
    for k in range(1, nu // 2):
        term *= c2 * (2 * k - 1) / (2 * k)
        total += term
    return s * total


def t_quantile(q: float, nu: int) -> float:
    """The ``q`` quantile (0.5 < q < 1) of Student's t with ``nu`` (whole, >= 1) degrees of freedom.

    Parameters
    ----------
    q : float
        Probability, above one half (the upper quantile).
    nu : int
        Degrees of freedom.

    Returns
    -------
    float
        t with P(T <= t) = q.
    """
    if not 0.5 < q < 1.0 or nu < 1:
        raise ValueError(f"t_quantile needs 0.5 < q < 1 and nu >= 1, not q={q}, nu={nu}")
    target = 2.0 * q - 1.0
    # d/dtheta of the central probability: its density in theta, 2 Gamma((nu+1)/2) / (sqrt(pi) Gamma(nu/2)) cos^(nu-1)
    scale = 2.0 * math.exp(math.lgamma((nu + 1) / 2.0) - math.lgamma(nu / 2.0)) / math.sqrt(math.pi)
    lo, hi = 0.0, math.pi / 2.0
    theta = math.atan(NormalDist().inv_cdf(q) / math.sqrt(nu))
    for _ in range(100):
        error = _central_probability(theta, nu) - target
        if error > 0.0:
            hi = theta
        else:
            lo = theta
        slope = scale * math.cos(theta) ** (nu - 1)
        step = theta - error / slope if slope > 0.0 else math.nan
        nxt = step if lo < step < hi else 0.5 * (lo + hi)  # Newton, kept inside the bracket
        if abs(nxt - theta) <= 1e-17 * max(theta, 1e-300) or nxt in (lo, hi):
            theta = nxt
            break
        theta = nxt
    return math.sqrt(nu) * math.tan(theta)


__all__ = ["t_quantile"]
