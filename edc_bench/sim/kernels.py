"""The simulated rig's arithmetic, one definition for one valve and for many: the plant's step, the coils'
heating, the sensors' reading.

:func:`step_valve` is the plant's step (paper eqs. 1-4 with stiction, :mod:`edc_bench.sim.plant`): a valve that
slides through the whole step takes it exactly (Phi and Gamma of the step); one that sticks, reverses or reaches a
stop is replayed in quanta with the Karnopp rule. :class:`~edc_bench.sim.plant.Plant`, the simulated rig's one
valve, calls it for every step it takes; the batch path's N valves (:class:`~edc_bench.population.batch._VectorPlant`)
call it through :func:`advance`. There is no other copy: the tests hold the batch's plant to N rig plants to the
bit (``tests/sim/test_kernels.py``).

For the batch path, compiled by numba where it is installed: in numpy the batch's Karnopp replay was a few dozen
array operations per quantum over the valves concerned, each paying numpy's call cost for a handful of values;
compiled, each valve is a few hundred floating-point operations, and a reading or the heat of a tick is one call
instead of four or five.
numba keeps the arithmetic as written (no fused multiply-add, no reassociation: its defaults; its rounding is
numpy's, half to even). The one function call, the Stribeck curve's exponential, is the C library's, as Python's
``math.exp`` is.

The functions below are plain Python: the simulated rig runs them so. :func:`compiled` gives the batch path the
same functions compiled by numba. Where numba has no wheel (a machine or Python it does not support) edc-bench
installs without it and the batch runs them as Python too: the same results, slower (``compiled().compiled`` is
False and the batch path says so once, :func:`speed_note`).
"""

from __future__ import annotations

import builtins
import functools
import math
import tempfile
import types
from pathlib import Path
from typing import Any

import numpy as np

from edc_bench.paths import cache_dir

#: The kernels, callees before callers (the order a compiled set is built in).
_KERNELS = ("_rack_friction", "_propagate", "_advance_fine", "step_valve", "advance", "dissipate", "quantised_reading")


@functools.cache
def compiled() -> types.SimpleNamespace:
    """The kernels compiled by numba, for the batch path: a namespace of :func:`step_valve`, :func:`advance`,
    :func:`dissipate`, :func:`quantised_reading` (and ``compiled``, True). Where numba is not installed, the Python
    functions of this module (``compiled`` False).

    Compiled on first call, not at import: the simulated rig's one valve runs the Python functions (numba's import
    and the compiled code's loading, over half a second with SciPy, are kept out of a test's start; its single
    valve's step costs microseconds either way). Each kernel is compiled from its own code, with the compiled
    versions of the kernels it calls: one definition, two ways to run it.
    """
    try:
        import numba
    except ImportError:  # no numba for this machine (pyproject installs it only where it has wheels)
        return types.SimpleNamespace(compiled=False, **{name: globals()[name] for name in _KERNELS})
    cache = _cache_folder(numba)
    namespace: dict[str, object] = {"__builtins__": builtins, "math": math, "np": np}
    for name in _KERNELS:
        function = globals()[name]
        copy = types.FunctionType(function.__code__, namespace, name, function.__defaults__)
        copy.__qualname__, copy.__module__, copy.__doc__ = function.__qualname__, function.__module__, function.__doc__
        namespace[name] = numba.njit(cache=cache, nogil=True)(copy)
    return types.SimpleNamespace(compiled=True, **{name: namespace[name] for name in _KERNELS})


def speed_note() -> str | None:
    """What a person running a batch should know of its speed here (None where the kernels are compiled)."""
    if compiled().compiled:
        return None
    return ("numba is not installed on this machine (it has no wheel for it): the batch path's simulated rig runs "
            "as Python, with the same results, many times slower; install numba where it installs to speed it up")


def _cache_folder(numba: Any) -> bool:
    """Keep the compiled kernels in edc-bench's cache folder (``EDC_BENCH_CACHE_DIR``; ``NUMBA_CACHE_DIR`` if set).

    numba's own choice, beside this file or in the user's cache, may be read-only on a station, and then it
    refuses the kernels. Where the folder cannot be written the kernels are compiled in each process instead
    (False).
    """
    folder = Path(numba.config.CACHE_DIR or cache_dir() / "numba")
    try:
        folder.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryFile(dir=folder):
            pass
    except OSError:
        return False
    numba.config.CACHE_DIR = str(folder)
    return True


def _rack_friction(x: float, pump: np.ndarray) -> float:
    """The rack's own friction beyond the valve's at position ``x`` (N): a local bind and a slope along the stroke
    (:meth:`~edc_bench.physics.parameters.PlantParameters.rack_friction_n`; 0 on a sound rack)."""
    if pump[10] == 0.0 and pump[13] == 0.0:
        return 0.0
    bind = 0.0
    if pump[10] != 0.0:
        q = (x - pump[11]) / pump[12]
        bind = pump[10] * math.exp(-(q * q))
    return bind + pump[13] * x


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
        friction += _rack_friction(mid_mm, pump)
        f = pump[3] * (mid_mm - pump[4]) * i - (pump[1] + friction * sign)
    xn = phi[0, j] * x + phi[1, j] * v + phi[2, j] * i + gam[0, j] * coil_v + gam[1, j] * f
    vn = phi[3, j] * x + phi[4, j] * v + phi[5, j] * i + gam[2, j] * coil_v + gam[3, j] * f
    i_n = phi[8, j] * i + gam[4, j] * coil_v
    return xn, vn, i_n


def pump_constants(linear: bool, preload_n: float, stribeck_velocity_mm_s: float, force_constant_n_per_a: float,
                   force_constant_slope_per_mm: float, force_constant_mid_mm: float, net_stiffness_n_per_mm: float,
                   stroke_mm: float, stick_speed_mm_s: float, rack_bind_n: float = 0.0, rack_bind_at_mm: float = 0.0,
                   rack_bind_width_mm: float = 1.0, rack_friction_slope_n_per_mm: float = 0.0) -> np.ndarray:
    """The pump's own numbers, packed for the kernels.

    The rack's own friction (a local bind, a slope: :class:`~edc_bench.physics.parameters.PlantParameters`) is the
    pump's, not the valve's; a pump with it is not the linear one (``linear`` False).

    Every number the kernels use comes in here at run time: a module constant would be compiled into the cached
    kernels, which numba does not compile again when only the module that defines it changes.
    """
    return np.array([1.0 if linear else 0.0, preload_n, stribeck_velocity_mm_s,
                     force_constant_n_per_a * force_constant_slope_per_mm, force_constant_mid_mm,
                     force_constant_n_per_a, force_constant_slope_per_mm, net_stiffness_n_per_mm, stroke_mm,
                     stick_speed_mm_s, rack_bind_n, rack_bind_at_mm, rack_bind_width_mm,
                     rack_friction_slope_n_per_mm])


def _advance_fine(j: int, steps: int, x: float, v: float, i: float, stuck: bool, phi_q: np.ndarray,
                  gam_q: np.ndarray, coil_v: float, fc: float, fs: float, quantum_s: float,
                  pump: np.ndarray) -> tuple[float, float, float, bool, int]:
    """Karnopp stepping of valve ``j`` in ``steps`` quanta; the last item: how often it came to stick (a
    reversal inside a quantum, or too slow against stiction; not the stops)."""
    ki, slope, x_mid, k, fpre, stroke, stick_speed = pump[5], pump[6], pump[4], pump[7], pump[1], pump[8], pump[9]
    sticks = 0
    for _ in range(steps):
        net = ki * (1.0 + slope * (x - x_mid)) * i - k * x - fpre
        hold = stuck and (abs(net) <= fs + _rack_friction(x, pump) or (x <= 0.0 and net <= 0.0)
                          or (x >= stroke and net >= 0.0))
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
            slow = abs(vn) < stick_speed and abs(pull - k * xn - fpre) <= fs + _rack_friction(xn, pump)
        new_stuck = reversed_ or slow
        if reversed_:
            frac = v / (v - vn) if v != vn else 0.0
            xn = x + frac * (xn - x)
        if new_stuck:
            vn = 0.0
            sticks += 1
        if xn <= 0.0 or xn >= stroke:
            xn = 0.0 if xn <= 0.0 else stroke
            vn = 0.0
            new_stuck = True
        x, v, i, stuck = xn, vn, i_n, new_stuck
    return x, v, i, stuck, sticks


def step_valve(phi: np.ndarray, gam: np.ndarray, m: int, dt_s: float, quanta: int, x: float, v: float, i: float,
               stuck: bool, phi_q: np.ndarray, gam_q: np.ndarray, j: int, coil_v: float, fc: float, fs: float,
               quantum_s: float, pump: np.ndarray) -> tuple[float, float, float, bool, int]:
    """One valve's plant over a step of ``quanta`` quanta (``dt_s``) under the coil voltage ``coil_v`` held.

    Parameters
    ----------
    phi, gam : numpy.ndarray
        (9, M) and (6, M): the exact step's Phi and Gamma (rows of the 3x3 and 3x2 matrices), column ``m``.
    m : int
        The step's column in ``phi`` and ``gam``.
    dt_s : float
        The step's length (``quanta`` quanta).
    quanta : int
        The step in quanta, replayed one by one where the exact step does not hold.
    x, v, i, stuck
        The valve's state: rack position (mm), speed (mm/s), coil current (A), held by stiction or a stop.
    phi_q, gam_q : numpy.ndarray
        A quantum's Phi and Gamma, column ``j``.
    j : int
        The valve's column in ``phi_q`` and ``gam_q``.
    coil_v : float
        The coil's voltage (the amplifier's output).
    fc, fs : float
        Coulomb and stiction friction (N).
    quantum_s : float
        A quantum's length.
    pump : numpy.ndarray
        The pump's constants, as :func:`pump_constants` packs them.

    Returns
    -------
    x, v, i, stuck
        The state after the step.
    sticks : int
        How often the valve came to stick within the step (0 when it slid through).
    """
    sign = 1.0 if v > 0.0 else -1.0
    if not stuck:
        xn, vn, i_n = _propagate(phi, gam, m, x, v, i, coil_v, sign, fc, fs, dt_s, pump)
        if vn * sign > pump[9] and xn > 0.0 and xn < pump[8]:
            return xn, vn, i_n, False, 0
    return _advance_fine(j, quanta, x, v, i, stuck, phi_q, gam_q, coil_v, fc, fs, quantum_s, pump)


def advance(valves: np.ndarray, quanta: np.ndarray, phi: np.ndarray, gam: np.ndarray, dt_s: np.ndarray,
            x: np.ndarray, v: np.ndarray, i: np.ndarray, stuck: np.ndarray, phi_q: np.ndarray, gam_q: np.ndarray,
            coil_v: np.ndarray, fc: np.ndarray, fs: np.ndarray, quantum_s: float, pumps: np.ndarray) -> None:
    """Advance valves ``valves[m]`` by ``quanta[m]`` quanta each, in place.

    ``phi``, ``gam`` (9 and 6 rows), ``dt_s`` and ``coil_v`` are per entry of ``valves`` (the exact step over
    those quanta, and the coil voltage held); the state ``x``, ``v``, ``i``, ``stuck`` and ``phi_q``, ``gam_q``
    (a quantum's step), ``fc``, ``fs`` and the rows of ``pumps`` (each valve's pump, as :func:`pump_constants`
    packs it: a pump's rack may bind where another's does not) are per valve of the batch. A valve that slides
    through takes the exact step; otherwise its quanta are replayed one by one from where it was
    (:func:`step_valve`, each).
    """
    for m in range(len(valves)):
        j = valves[m]
        x[j], v[j], i[j], stuck[j], _ = step_valve(phi, gam, m, dt_s[m], quanta[m], x[j], v[j], i[j], stuck[j],
                                                   phi_q, gam_q, j, coil_v[m], fc[j], fs[j], quantum_s, pumps[j])


def dissipate(heat_j: np.ndarray, resistance_ohm: np.ndarray, i: np.ndarray, dt_s: float) -> None:
    """Add each coil's ``R i^2`` over ``dt_s`` to ``heat_j``, in place (one call a tick instead of four numpy ones)."""
    for j in range(len(heat_j)):
        heat_j[j] += resistance_ohm[j] * i[j] * i[j] * dt_s


def quantised_reading(value: np.ndarray, offset: float, noise: np.ndarray, step: float) -> np.ndarray:
    """A sensor's reading of ``value``: offset and noise added, rounded (half to even) to its ``step``."""
    out = np.empty(len(value))
    for j in range(len(value)):
        out[j] = np.round((value[j] + offset + noise[j]) / step) * step
    return out
