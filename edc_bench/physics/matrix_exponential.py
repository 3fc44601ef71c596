"""The matrix exponential of the small plant matrices, in numpy alone (Higham's scaling and squaring).

The simulated rig discretises its plant exactly (``expm`` of the augmented
state matrix) when it is built, before a test's first tick; importing
scipy.linalg for it made that start noticeably longer. This is the
algorithm of Higham (2005), "The scaling and squaring method for the matrix
exponential revisited" (SIAM J. Matrix Anal. Appl. 26(4)): the lowest Pade
degree whose error bound holds for the matrix's 1-norm, after halving the
matrix until it does. A test holds it to scipy.linalg.expm's figures.
"""

from __future__ import annotations

import math

import numpy as np

# Pade coefficients b_0..b_m of degree m, and the largest 1-norm each degree serves to double precision
_PADE = {
    3: (120.0, 60.0, 12.0, 1.0),
    5: (30240.0, 15120.0, 3360.0, 420.0, 30.0, 1.0),
    7: (17297280.0, 8648640.0, 1995840.0, 277200.0, 25200.0, 1512.0, 56.0, 1.0),
    9: (17643225600.0, 8821612800.0, 2075673600.0, 302702400.0, 30270240.0, 2162160.0, 110880.0, 3960.0, 90.0,
        1.0),
    13: (64764752532480000.0, 32382376266240000.0, 7771770303897600.0, 1187353796428800.0, 129060195264000.0,
         10559470521600.0, 670442572800.0, 33522128640.0, 1323241920.0, 40840800.0, 960960.0, 16380.0, 182.0,
         1.0),
}
_THETA = {3: 1.495585217958292e-2, 5: 2.539398330063230e-1, 7: 9.504178996162932e-1, 9: 2.097847961257068,
          13: 5.371920351148152}


def expm(a: np.ndarray) -> np.ndarray:
    """exp(``a``) of a square matrix, or of each matrix in a stack.

    Parameters
    ----------
    a : numpy.ndarray
        (n, n) float matrix, or (..., n, n) matrices.

    Returns
    -------
    numpy.ndarray
        The matrix exponential(s), shaped as ``a``.

    Each matrix gets the degree and the squarings its own 1-norm calls for; matrices that call for the same are
    computed together (the batch path's valves mostly do), so a stack costs a few numpy operations, not one
    Python pass per matrix.
    """
    a = np.asarray(a, dtype=float)
    if a.ndim == 2:
        return _scaled_pade(a, *_plan(float(np.abs(a).sum(axis=0).max()) if a.size else 0.0))
    stack = a.reshape((-1,) + a.shape[-2:])
    norms = np.abs(stack).sum(axis=-2).max(axis=-1) if stack.size else np.zeros(len(stack))
    # as _plan, over the stack: the degree's index in _DEGREES, and the squarings (degree 13 only)
    choice = np.searchsorted(_LIMITS, norms)  # norm <= _THETA[d]: the first such degree
    with np.errstate(divide="ignore"):
        squarings = np.where(choice == len(_DEGREES) - 1,
                             np.maximum(0, np.ceil(np.log2(norms / _THETA[13]))), 0).astype(int)
    plans = choice * 10_000 + squarings
    out = np.empty_like(stack)
    for plan in np.unique(plans):
        members = plans == plan
        out[members] = _scaled_pade(stack[members], _DEGREES[plan // 10_000], int(plan % 10_000))
    return out.reshape(a.shape)


def _scaled_pade(a: np.ndarray, degree: int, squarings: int) -> np.ndarray:
    """exp(a) as the Pade approximant of a / 2^squarings, squared back."""
    result = _pade(a / 2.0**squarings, degree)
    for _ in range(squarings):
        result = result @ result
    return result


_DEGREES = (3, 5, 7, 9, 13)
_LIMITS = np.array([_THETA[d] for d in _DEGREES[:-1]])


def _plan(norm: float) -> tuple[int, int]:
    """The Pade degree and the number of squarings for a matrix of 1-norm ``norm``."""
    for degree in (3, 5, 7, 9):
        if norm <= _THETA[degree]:
            return degree, 0
    return 13, max(0, math.ceil(math.log2(norm / _THETA[13])))


def _pade(a: np.ndarray, degree: int) -> np.ndarray:
    """The [degree/degree] Pade approximant of exp(a), a (n, n) or (k, n, n): (V - U)^-1 (V + U), U the odd part,
    V the even."""
    b = _PADE[degree]
    eye = np.broadcast_to(np.eye(a.shape[-1]), a.shape)
    a2 = a @ a
    if degree == 13:
        a4 = a2 @ a2
        a6 = a4 @ a2
        u = a @ (a6 @ (b[13] * a6 + b[11] * a4 + b[9] * a2) + b[7] * a6 + b[5] * a4 + b[3] * a2 + b[1] * eye)
        v = a6 @ (b[12] * a6 + b[10] * a4 + b[8] * a2) + b[6] * a6 + b[4] * a4 + b[2] * a2 + b[0] * eye
    else:
        powers = [eye, a2]
        for _ in range(2, degree // 2 + 1):
            powers.append(powers[-1] @ a2)
        u = a @ sum(b[2 * k + 1] * p for k, p in enumerate(powers))
        v = sum(b[2 * k] * p for k, p in enumerate(powers))
    return np.linalg.solve(v - u, v + u)


__all__ = ["expm"]
