"""The simulated rig's arithmetic per valve, compiled: the plant's step, the coils' heating, the sensors' reading.

:class:`~edc_bench.population.batch._VectorPlant` and ``_Sensors`` hold N valves' state and coefficients as
arrays; these kernels work on them. A valve that slides through the whole step takes it exactly (Phi and Gamma
of the period); one that sticks, reverses or reaches a stop is replayed in quanta with the Karnopp rule of
:class:`~edc_bench.sim.plant.Plant`. In numpy that replay was a few dozen array operations per quantum over the
valves concerned, each paying numpy's call cost for a handful of values. Compiled by numba, each valve is a few
hundred floating-point operations, and a reading or the heat of a tick is one call instead of four or five.

The arithmetic is the numpy version's, operation for operation and in the same order (no fused multiply-add, no
reassociation: numba's defaults; numba's rounding is numpy's, half to even), so a linear pump's results are the
same to the bit (``tests/population/test_rig_kernels.py`` holds the kernels to the numpy version). The one function
call, the Stribeck curve's exponential, is the C library's, as the simulated rig's plant takes it; numpy's own
(vectorised where the CPU has AVX-512) differs from it in the last bit for some arguments, so a Stribeck pump's
state can differ from the numpy version's in its last bits (the hard variant's model still rebuilt byte for byte).

Where numba has no wheel (a machine or Python it does not support) edc-bench installs without it and these
kernels run as the Python they are written in: the same results, far slower (:data:`COMPILED` is False and the
batch path says so once, :func:`speed_note`).
"""

from __future__ import annotations

import math
import tempfile
from pathlib import Path

from collections.abc import Callable
from typing import Any

import numpy as np

from edc_bench.paths import cache_dir

try:
    import numba
    from numba import njit
except ImportError:  # no numba for this machine (pyproject installs it only where it has wheels)
    numba = None

    def njit(*_args: Any, **_options: Any) -> Callable[[Callable[..., Any]], Callable[..., Any]]:  # type: ignore[no-redef]
        """numba's decorator where numba is not installed: the function as written."""
        return lambda function: function

#: The kernels run compiled by numba (False: as Python, where numba is not installed).
COMPILED = numba is not None


def speed_note() -> str | None:
    """What a person running a batch should know of its speed here (None where the kernels are compiled)."""
    if COMPILED:
        return None
    return ("numba is not installed on this machine (it has no wheel for it): the batch path's simulated rig runs "
            "as Python, with the same results, many times slower; install numba where it installs to speed it up")


def _cache_folder() -> bool:
    """Keep the compiled kernels in edc-bench's cache folder (``EDC_BENCH_CACHE_DIR``; ``NUMBA_CACHE_DIR`` if set).

    numba's own choice, beside this file or in the user's cache, may be read-only on a station, and then it
    refuses the module at import. Where the folder cannot be written the kernels are compiled in each process
    instead (False).
    """
    if numba is None:
        return False
    folder = Path(numba.config.CACHE_DIR or cache_dir() / "numba")
    try:
        folder.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryFile(dir=folder):
            pass
    except OSError:
        return False
    numba.config.CACHE_DIR = str(folder)
    return True


_CACHE = _cache_folder()


@njit(cache=_CACHE, nogil=True)
def _propagate(phi: np.ndarray, gam: np.ndarray, j: int, x: float, v: float, i: float, coil_v: float,
               sign: float, fc: float, fs: float, dt_s: float, pump: np.ndarray) -> tuple[float, float, float]:
    """One exact step of valve ``j`` (columns of Phi and Gamma) under friction ``sign``; ``pump`` as
    :func:`pump_constants` packs it."""
    if pump[0] != 0.0:  # the linear pump
        f = -(pump[1] + fc * sign)
    else:  # the departures from the linear model, held over the step (sim.plant's module docstring)
        friction = fc
        if pump[2] > 0.0:
            q = v / pump[2]
            friction = fc + (fs - fc) * math.exp(-(q * q))
        mid_mm = x + 0.5 * dt_s * v
        f = pump[3] * (mid_mm - pump[4]) * i - (pump[1] + friction * sign)
    xn = phi[0, j] * x + phi[1, j] * v + phi[2, j] * i + gam[0, j] * coil_v + gam[1, j] * f
    vn = phi[3, j] * x + phi[4, j] * v + phi[5, j] * i + gam[2, j] * coil_v + gam[3, j] * f
    i_n = phi[8, j] * i + gam[4, j] * coil_v
    return xn, vn, i_n


def pump_constants(linear: bool, preload_n: float, stribeck_velocity_mm_s: float, force_constant_n_per_a: float,
                   force_constant_slope_per_mm: float, force_constant_mid_mm: float, net_stiffness_n_per_mm: float,
                   stroke_mm: float, stick_speed_mm_s: float) -> np.ndarray:
    """The pump's own numbers, the same for every valve, packed for the kernels.

    Every number the kernels use comes in here at run time: a module constant would be compiled into the cached
    kernels, which numba does not compile again when only the module that defines it changes.
    """
    return np.array([1.0 if linear else 0.0, preload_n, stribeck_velocity_mm_s,
                     force_constant_n_per_a * force_constant_slope_per_mm, force_constant_mid_mm,
                     force_constant_n_per_a, force_constant_slope_per_mm, net_stiffness_n_per_mm, stroke_mm,
                     stick_speed_mm_s])


@njit(cache=_CACHE, nogil=True)
def _advance_fine(j: int, steps: int, x: float, v: float, i: float, stuck: bool, phi_q: np.ndarray,
                  gam_q: np.ndarray, coil_v: float, fc: float, fs: float, quantum_s: float,
                  pump: np.ndarray) -> tuple[float, float, float, bool]:
    """Karnopp stepping of valve ``j`` in ``steps`` quanta."""
    ki, slope, x_mid, k, fpre, stroke, stick_speed = pump[5], pump[6], pump[4], pump[7], pump[1], pump[8], pump[9]
    for _ in range(steps):
        net = ki * (1.0 + slope * (x - x_mid)) * i - k * x - fpre
        hold = stuck and (abs(net) <= fs or (x <= 0.0 and net <= 0.0) or (x >= stroke and net >= 0.0))
        if stuck:
            sign = 1.0 if net > 0.0 else -1.0
        else:
            sign = 1.0 if v > 0.0 else -1.0
        if hold:  # held racks: only the current evolves
            i = phi_q[8, j] * i + gam_q[4, j] * coil_v
            v = 0.0
            continue
        xn, vn, i_n = _propagate(phi_q, gam_q, j, x, v, i, coil_v, sign, fc, fs, quantum_s, pump)
        reversed_ = vn * sign <= 0.0
        slow = False
        if not reversed_:
            pull = ki * (1.0 + slope * (xn - x_mid)) * i_n
            slow = abs(vn) < stick_speed and abs(pull - k * xn - fpre) <= fs
        new_stuck = reversed_ or slow
        if reversed_:
            frac = v / (v - vn) if v != vn else 0.0
            xn = x + frac * (xn - x)
        if new_stuck:
            vn = 0.0
        if xn <= 0.0 or xn >= stroke:
            xn = 0.0 if xn <= 0.0 else stroke
            vn = 0.0
            new_stuck = True
        x, v, i, stuck = xn, vn, i_n, new_stuck
    return x, v, i, stuck


@njit(cache=_CACHE, nogil=True)
def advance(valves: np.ndarray, quanta: np.ndarray, phi: np.ndarray, gam: np.ndarray, dt_s: np.ndarray,
            x: np.ndarray, v: np.ndarray, i: np.ndarray, stuck: np.ndarray, phi_q: np.ndarray, gam_q: np.ndarray,
            coil_v: np.ndarray, fc: np.ndarray, fs: np.ndarray, quantum_s: float, pump: np.ndarray) -> None:
    """Advance valves ``valves[m]`` by ``quanta[m]`` quanta each, in place.

    ``phi``, ``gam`` (9 and 6 rows), ``dt_s`` and ``coil_v`` are per entry of ``valves`` (the exact step over
    those quanta, and the coil voltage held); the state ``x``, ``v``, ``i``, ``stuck`` and ``phi_q``, ``gam_q``
    (a quantum's step), ``fc``, ``fs`` are per valve of the batch. A valve that slides through takes the exact
    step; otherwise its quanta are replayed one by one from where it was.
    """
    stroke, stick_speed = pump[8], pump[9]
    for m in range(len(valves)):
        j = valves[m]
        xj, vj, ij = x[j], v[j], i[j]
        sign = 1.0 if vj > 0.0 else -1.0
        xn, vn, i_n = _propagate(phi, gam, m, xj, vj, ij, coil_v[m], sign, fc[j], fs[j], dt_s[m], pump)
        if not stuck[j] and vn * sign > stick_speed and xn > 0.0 and xn < stroke:
            x[j], v[j], i[j] = xn, vn, i_n
        else:
            x[j], v[j], i[j], stuck[j] = _advance_fine(j, quanta[m], xj, vj, ij, stuck[j], phi_q, gam_q, coil_v[m],
                                                       fc[j], fs[j], quantum_s, pump)


@njit(cache=_CACHE, nogil=True)
def dissipate(heat_j: np.ndarray, resistance_ohm: np.ndarray, i: np.ndarray, dt_s: float) -> None:
    """Add each coil's ``R i^2`` over ``dt_s`` to ``heat_j``, in place (one call a tick instead of four numpy ones)."""
    for j in range(len(heat_j)):
        heat_j[j] += resistance_ohm[j] * i[j] * i[j] * dt_s


@njit(cache=_CACHE, nogil=True)
def quantised_reading(value: np.ndarray, offset: float, noise: np.ndarray, step: float) -> np.ndarray:
    """A sensor's reading of ``value``: offset and noise added, rounded (half to even) to its ``step``."""
    out = np.empty(len(value))
    for j in range(len(value)):
        out[j] = np.round((value[j] + offset + noise[j]) / step) * step
    return out
