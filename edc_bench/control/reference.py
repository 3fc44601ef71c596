"""Rack reference: soft start to mid-stroke, then a sum of sines, with exact
derivatives up to the third.

    r(t) = x0 + (r_mid - x0) S((t - 0) / T_move)                 move
         + E((t - T_move) / T_fade) sum_j A_j sin(w_j (t - T_move))  excitation

S and E are C3 smoothsteps (degree-7 polynomials with zero first to third
derivatives at both ends), so r, r', r'' and r''' are continuous: the first
tick does not jump and the feedforward's r''' term never spikes. Derivatives
of the product E * sines come from Leibniz' rule.

With one tone, r''' = -w^2 r' exactly and r'' = -w^2 (r - r_mid): a3 and a1
cannot be told apart (docs/method.md section 10 d). Use two tones or more.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np


@dataclass(frozen=True)
class Tone:
    """One sine of the excitation."""

    frequency_hz: float
    amplitude_mm: float
    phase_rad: float = 0.0


def smoothstep7(u: float) -> tuple[float, float, float, float]:
    """C3 smoothstep and its first three derivatives with respect to ``u``.

    ``S(u) = 35u^4 - 84u^5 + 70u^6 - 20u^7`` on [0, 1], 0 before, 1 after.
    """
    return _smoothstep7_polynomial(_clip_unit(u))


def _clip_unit(u: float) -> float:
    return 0.0 if u <= 0.0 else (1.0 if u >= 1.0 else u)


def _smoothstep7_polynomial(u):
    """The polynomial of :func:`smoothstep7` (for u in [0, 1]; floats or arrays)."""
    u2 = u * u
    u3 = u2 * u
    u4 = u3 * u
    s = u4 * (35.0 - 84.0 * u + 70.0 * u2 - 20.0 * u3)
    d1 = u3 * (140.0 - 420.0 * u + 420.0 * u2 - 140.0 * u3)
    d2 = u2 * (420.0 - 1680.0 * u + 2100.0 * u2 - 840.0 * u3)
    d3 = u * (840.0 - 5040.0 * u + 8400.0 * u2 - 4200.0 * u3)
    return s, d1, d2, d3


class Reference:
    """The reference of one bench test.

    Parameters
    ----------
    start_mm : float
        Rack position when the test starts (measured).
    mid_mm : float
        Centre of the excitation (mid-stroke).
    tones : sequence of Tone
        The excitation.
    move_s : float
        Duration of the smooth move from ``start_mm`` to ``mid_mm``.
    fade_s : float
        Duration of the excitation's smooth fade-in, after the move.
    """

    def __init__(self, start_mm: float, mid_mm: float, tones: tuple[Tone, ...], move_s: float,
                 fade_s: float) -> None:
        if move_s <= 0 or fade_s <= 0:
            raise ValueError("move_s and fade_s must be positive")
        self.start_mm = start_mm
        self.mid_mm = mid_mm
        self.tones = tuple(tones)
        self.move_s = move_s
        self.fade_s = fade_s
        self._w = tuple(2.0 * math.pi * t.frequency_hz for t in self.tones)

    @property
    def excitation_start_s(self) -> float:
        """Time at which the excitation begins (end of the move)."""
        return self.move_s

    @property
    def peak_velocity_mm_s(self) -> float:
        """Upper bound of |r'| during the excitation."""
        return sum(t.amplitude_mm * w for t, w in zip(self.tones, self._w, strict=True))

    def at(self, t_s: float) -> tuple[float, float, float, float]:
        """``(r, r', r'', r''')`` at time ``t_s`` (mm, mm/s, mm/s^2, mm/s^3)."""
        return self._evaluate(t_s, math.sin, math.cos, _clip_unit)

    def tabulate(self, t_s: np.ndarray) -> np.ndarray:
        """:meth:`at` for many times at once: rows r, r', r'', r''' (shape ``(4, len(t_s))``).

        The same arithmetic as :meth:`at`, vectorised, so a test's whole
        reference costs about a millisecond up front instead of a few
        microseconds in every tick.
        """
        t = np.asarray(t_s, dtype=float)
        return np.array(self._evaluate(t, np.sin, np.cos, lambda u: np.clip(u, 0.0, 1.0)))

    def _evaluate(self, t_s, sin, cos, clip):
        return compose(self.start_mm, self.mid_mm, self.move_s, self.shape(t_s, sin, cos, clip))

    def shape(self, t_s: Any, sin: Any = np.sin, cos: Any = np.cos,
              clip: Any = lambda u: np.clip(u, 0.0, 1.0)) -> Shape:
        """What the reference is at ``t_s`` whatever its start: the move's smoothstep and the excitation's terms
        (:class:`Shape`); :func:`compose` adds a start. Floats with ``math``'s functions, arrays with numpy's."""
        # Branch-free: the smoothstep polynomials of a clipped argument are 0 before
        # and 1 after with zero derivatives, so one expression serves floats and arrays.
        s0, s1, s2, s3 = _smoothstep7_polynomial(clip(t_s / self.move_s))
        tau = t_s - self.move_s
        # sum of sines and its derivatives
        g0 = g1 = g2 = g3 = 0.0
        for tone, w in zip(self.tones, self._w, strict=True):
            phase = w * tau + tone.phase_rad
            sn = tone.amplitude_mm * sin(phase)
            cs = tone.amplitude_mm * cos(phase)
            g0 = g0 + sn
            g1 = g1 + w * cs
            g2 = g2 - w * w * sn
            g3 = g3 - w * w * w * cs
        e0, e1, e2, e3 = _smoothstep7_polynomial(clip(tau / self.fade_s))
        f = 1.0 / self.fade_s
        e1 = e1 * f
        e2 = e2 * (f * f)
        e3 = e3 * (f * f * f)
        # Leibniz: (E g)^(n) = sum C(n,k) E^(k) g^(n-k)
        return Shape((s0, s1, s2, s3), (e0 * g0,), (e0 * g1, e1 * g0), (e0 * g2, 2.0 * e1 * g1, e2 * g0),
                     (e0 * g3, 3.0 * e1 * g2, 3.0 * e2 * g1, e3 * g0))


@dataclass(frozen=True)
class Shape:
    """A reference at some times, its start aside: the move's smoothstep and its first three derivatives (per unit
    of the move's time), and the terms of the excitation's r and its first three derivatives (Leibniz's rule's
    terms, each in the order they are summed). Floats, or arrays of one length."""

    move: tuple[Any, Any, Any, Any]
    excitation_r: tuple[Any]
    excitation_r1: tuple[Any, Any]
    excitation_r2: tuple[Any, Any, Any]
    excitation_r3: tuple[Any, Any, Any, Any]

    def at(self, k: int) -> Shape:
        """The shape at the ``k``-th of its times (a shape of arrays)."""
        return Shape(*(tuple(term[k] for term in terms) for terms in  # type: ignore[arg-type]
                       (self.move, self.excitation_r, self.excitation_r1, self.excitation_r2, self.excitation_r3)))


def compose(start_mm: Any, mid_mm: float, move_s: float, shape: Shape) -> tuple[Any, Any, Any, Any]:
    """The reference that starts at ``start_mm``, and its first three derivatives, at the times of ``shape``: its move
    from the start to ``mid_mm`` plus the excitation, in one order of operations, so a start given as a float (the
    loop's controller) and as an array of starts (the batch path's valves) give the same bits for the same start."""
    span = mid_mm - start_mm
    _, s1, s2, s3 = shape.move
    inv = 1.0 / move_s
    r1 = span * s1 * inv
    r2 = span * s2 * inv * inv
    r3 = span * s3 * inv * inv * inv
    (x1a, x1b), (x2a, x2b, x2c), (x3a, x3b, x3c, x3d) = shape.excitation_r1, shape.excitation_r2, shape.excitation_r3
    return (compose_position(start_mm, mid_mm, shape), r1 + x1a + x1b, r2 + x2a + x2b + x2c,
            r3 + x3a + x3b + x3c + x3d)


def compose_position(start_mm: Any, mid_mm: float, shape: Shape) -> Any:
    """The reference alone (no derivative), as :func:`compose` gives it."""
    return start_mm + (mid_mm - start_mm) * shape.move[0] + shape.excitation_r[0]
