"""The controller's primitives for one test, in Python floats and lists (:data:`~edc_bench.control.law.SCALAR`).

:mod:`~edc_bench.control.law` writes the controller in these primitives and
implements them again for numpy arrays (``ArrayOps``); this module is the
float side: a dot product or the covariance's rank-one update over Python
floats, in the order the array side keeps, so both round alike.
"""

from __future__ import annotations

import math
from typing import Any



class Ops:
    """The primitives the law is written in, for Python floats and lists (one test).

    A vector is a list of floats; a matrix a list of lists. ``ok`` masks say for which tests an update applies
    (a bool here).
    """

    @staticmethod
    def where(condition: Any, a: Any, b: Any) -> Any:
        """``a`` where ``condition`` holds, else ``b``."""
        return a if condition else b

    @staticmethod
    def clip(x: float, limit: float) -> float:
        """``x`` within +/- ``limit``."""
        return limit if x > limit else (-limit if x < -limit else x)

    @staticmethod
    def isnan(x: float) -> bool:
        """NaN (here: no previous error)."""
        return x != x

    @staticmethod
    def isfinite(x: float) -> bool:
        """Neither NaN nor infinite."""
        return math.isfinite(x)

    @staticmethod
    def any(x: bool) -> bool:
        """Whether any test has it."""
        return bool(x)

    @staticmethod
    def sign(x: float) -> float:
        """+1, -1 or 0 as ``x`` is positive, negative or zero."""
        return 1.0 if x > 0.0 else (-1.0 if x < 0.0 else 0.0)

    @staticmethod
    def scaled_rows(w: list[float], rows: tuple[int, ...], scales: tuple[float, ...]) -> list[float]:
        """``[w[rows[j]] * scales[j]]``: the chosen entries, each scaled."""
        return [w[i] * s for i, s in zip(rows, scales)]

    @staticmethod
    def weighted_rows(w: list[float], weights: tuple[tuple[int, float], ...]) -> float:
        """``sum(a w[i])`` over the ``(i, a)`` pairs, from 0 and in their order (0 with no pair)."""
        out = 0.0
        for i, a in weights:
            out += a * w[i]
        return out

    @staticmethod
    def dot(a: list[float], b: list[float]) -> float:
        """``sum(a_j b_j)``."""
        out = 0.0
        for x, y in zip(a, b):
            out += x * y
        return out

    @staticmethod
    def matvec(m: list[list[float]], v: list[float]) -> list[float]:
        """``m v``."""
        out = []
        for row in m:
            acc = 0.0
            for x, y in zip(row, v):
                acc += x * y
            out.append(acc)
        return out

    @staticmethod
    def divide(v: list[float], d: float) -> list[float]:
        """``v / d``."""
        return [x / d for x in v]

    @staticmethod
    def multiply(a: list[float], b: list[float]) -> list[float]:
        """Element by element."""
        return [x * y for x, y in zip(a, b)]

    @staticmethod
    def add_scaled(v: list[float], g: list[float], s: float, ok: bool) -> None:
        """``v += g s`` in place, where ``ok``."""
        if ok:
            for i, gi in enumerate(g):
                v[i] += gi * s

    @staticmethod
    def rank_one_down(m: list[list[float]], g: list[float], h: list[float], scale: float, ok: bool) -> None:
        """``m = (m - g h^T) scale`` in place, where ``ok``; ``m`` symmetric and ``g`` parallel to ``h`` (the RLS
        covariance), so the upper triangle is computed and mirrored, which keeps ``m`` exactly symmetric."""
        if ok:
            n = len(h)
            for i in range(n):
                row, gi = m[i], g[i]
                for j in range(i, n):
                    v = (row[j] - gi * h[j]) * scale
                    row[j] = v
                    m[j][i] = v

    @staticmethod
    def bound_trace(m: list[list[float]], max_trace: float) -> None:
        """Scale ``m`` down to ``trace(m) = max_trace`` where it is more."""
        trace = 0.0
        for i, row in enumerate(m):
            trace += row[i]
        if trace > max_trace:
            scale = max_trace / trace
            for row in m:
                for j in range(len(row)):
                    row[j] *= scale


__all__ = ["Ops"]
