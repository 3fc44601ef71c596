"""A simulated pump whose control rack or rack-travel sensor is faulty (``--rack-fault``, ``--sensor-fault``).

On a P-EDC in-line pump the fuel-injection module has three parts that wear or fail: the solenoid valve the bench
was built for, the control rack it moves, and the rack-travel sensor that reads the rack's position. The rack and
its sensor belong to the pump on the rig, not to the rig: a customer pump brings their faults with it. Here they are
properties of the simulated pump, with physics of their own (docs/diagnosis.md, "Which part is at fault"):

**The rack** (:class:`RackFault`), as friction the valve does not cause:

- a guide that drags along the whole stroke (dry, dirty, a swollen seal): Coulomb friction and viscous drag
  added uniformly (``drag_n``, ``drag_damping_n_s_per_mm``);
- a bent rack or a burr that rubs at one place: friction higher by ``bind_n`` about ``bind_at_mm`` over
  ``bind_width_mm``, sliding and at rest;
- a guide whose friction rises along the stroke (``slope_n_per_mm``, from the stop).

**The sensor** (:class:`SensorFault`), as a reading the rack does not cause::

    reading = gain * x + offset_mm + bow_mm * 4 (x / S)(1 - x / S) + step + noise    (S the stroke)
    step = step_mm (1 + tanh((x - step_at_mm) / step_width_mm)) / 2                  (a track that reads unevenly)

plus contact dropouts (the reading falls to the sensor's zero for ``dropout_ms``, ``dropouts_per_s`` on average)
and spikes (one reading ``spike_mm`` off, ``spikes_per_s`` on average), both at random times of a seeded stream.
The variant's own sensor model (its offset, noise, resolution) and a rig's drift (:mod:`edc_bench.sim.drift`) are
applied on top, as a real sensor's signal passes the rig's conditioning.
"""

from __future__ import annotations

import dataclasses
import math
import types
from collections.abc import Sequence
from dataclasses import dataclass, fields
from typing import TypeVar

import numpy as np

from edc_bench.errors import ConfigError
from edc_bench.physics.parameters import PlantParameters
from edc_bench.sim.spec_pairs import pair_value


@dataclass(frozen=True)
class RackFault:
    """How the simulated pump's control rack binds or drags (none by default).

    Attributes
    ----------
    drag_n : float
        Coulomb friction added along the whole stroke (N): a dragging guide.
    drag_damping_n_s_per_mm : float
        Viscous drag added along the whole stroke (N s/mm).
    bind_n : float
        Friction added at one place (N, at its peak): a bent rack or a burr rubbing.
    bind_at_mm, bind_width_mm : float
        Where the bind is (mm from the stop) and how wide (mm, the Gaussian's 1/e half width).
    slope_n_per_mm : float
        Friction rising along the stroke (N per mm from the stop).
    spring_rel, preload_rel : float
        This pump's return spring against the pump type's (``[rack]``): its rate and its preload off by these shares
        (0.03: 3 % stiffer). Not a fault: pumps of one type differ within the spring's tolerance
        (``[rack] spring_tolerance_rel``, ``preload_tolerance_rel``), and the part diagnosis must not take that
        for a fault of the sensor.
    """

    drag_n: float = 0.0
    drag_damping_n_s_per_mm: float = 0.0
    bind_n: float = 0.0
    bind_at_mm: float = 12.0
    bind_width_mm: float = 1.0
    slope_n_per_mm: float = 0.0
    spring_rel: float = 0.0
    preload_rel: float = 0.0

    @property
    def none(self) -> bool:
        """True for a sound rack on the pump type's nominal spring."""
        return self.drag_n == 0.0 and self.drag_damping_n_s_per_mm == 0.0 and self.bind_n == 0.0 \
            and self.slope_n_per_mm == 0.0 and self.spring_rel == 0.0 and self.preload_rel == 0.0

    def spec(self) -> str:
        """The ``--rack-fault`` text that gives this fault (``none`` for none)."""
        return _spec_of(self, RackFault())

    def applied(self, params: PlantParameters, stiction_ratio: float) -> PlantParameters:
        """The pump's plant with this rack: its drag added to the valve's friction (breakaway by the valve's
        ``stiction_ratio``) and damping, its bind and slope as friction that depends on the position, its spring's
        rate and preload."""
        if self.none:
            return params
        return dataclasses.replace(
            params,
            spring_n_per_mm=params.spring_n_per_mm * (1.0 + self.spring_rel),
            preload_n=params.preload_n * (1.0 + self.preload_rel),
            coulomb_friction_n=params.coulomb_friction_n + self.drag_n,
            stiction_friction_n=params.stiction_friction_n + self.drag_n * stiction_ratio,
            damping_n_s_per_mm=params.damping_n_s_per_mm + self.drag_damping_n_s_per_mm,
            rack_bind_n=self.bind_n, rack_bind_at_mm=self.bind_at_mm, rack_bind_width_mm=self.bind_width_mm,
            rack_friction_slope_n_per_mm=self.slope_n_per_mm)


@dataclass(frozen=True)
class SensorFault:
    """How the simulated pump's rack-travel sensor misreads (none by default).

    Attributes
    ----------
    gain : float
        Scale of the reading (1: none; 1.08 reads 8 % long).
    offset_mm : float
        Zero shift of the reading (mm).
    bow_mm : float
        Non-linearity: the reading's bow at mid-stroke, zero at both ends (mm).
    step_mm, step_at_mm, step_width_mm : float
        Non-linearity over a few millimetres: the reading rises by ``step_mm`` more than the rack does about
        ``step_at_mm`` (a tanh step of half width ``step_width_mm``; the reading at rest unchanged), as a worn or
        contaminated track of the sensor reads.
    noise_sd_mm : float
        Noise added to every reading (mm, standard deviation).
    dropouts_per_s, dropout_ms : float
        A bad contact: on average this many dropouts a second, each reading the sensor's zero for ``dropout_ms``.
    spikes_per_s, spike_mm : float
        Interference: on average this many single readings a second, each ``spike_mm`` off (either sign).
    """

    gain: float = 1.0
    offset_mm: float = 0.0
    bow_mm: float = 0.0
    step_mm: float = 0.0
    step_at_mm: float = 12.0
    step_width_mm: float = 1.0
    noise_sd_mm: float = 0.0
    dropouts_per_s: float = 0.0
    dropout_ms: float = 3.0
    spikes_per_s: float = 0.0
    spike_mm: float = 0.5

    @property
    def none(self) -> bool:
        """True for a sound sensor."""
        return self.gain == 1.0 and self.offset_mm == 0.0 and self.bow_mm == 0.0 and self.step_mm == 0.0 \
            and self.noise_sd_mm == 0.0 \
            and self.dropouts_per_s == 0.0 and self.spikes_per_s == 0.0

    def spec(self) -> str:
        """The ``--sensor-fault`` text that gives this fault (``none`` for none)."""
        return _spec_of(self, SensorFault())


class FaultySensorReading:
    """The faulty sensor's reading of the true rack position, sample by sample (seeded, time-explicit).

    Parameters
    ----------
    fault : SensorFault
    stroke_mm : float
        The rack's stroke (the bow is zero at both ends).
    rng : numpy.random.Generator
        Source of the noise and of the dropouts' and spikes' times; the variant's own noise has a stream of its own.
    """

    def __init__(self, fault: SensorFault, stroke_mm: float, rng: np.random.Generator) -> None:
        self.fault = fault
        self._stroke_mm = stroke_mm
        self._rng = rng
        self._dropout_until_s = -math.inf
        self._next_dropout_s = self._after(0.0, fault.dropouts_per_s)
        self._next_spike_s = self._after(0.0, fault.spikes_per_s)
        self.dropouts = 0
        self.spikes = 0

    def _after(self, t_s: float, rate_per_s: float) -> float:
        return t_s + float(self._rng.exponential(1.0 / rate_per_s)) if rate_per_s > 0 else math.inf

    def read(self, x_mm: float, t_s: float) -> float:
        """The sensor's signal (mm) for the rack at ``x_mm`` at time ``t_s``, before the rig's conditioning."""
        f = self.fault
        if t_s >= self._next_dropout_s:
            self._dropout_until_s = t_s + f.dropout_ms * 1e-3
            self._next_dropout_s = self._after(t_s, f.dropouts_per_s)
            self.dropouts += 1
        if t_s < self._dropout_until_s:
            return 0.0
        u = x_mm / self._stroke_mm
        value = f.gain * x_mm + f.offset_mm + f.bow_mm * 4.0 * u * (1.0 - u)
        if f.step_mm != 0.0:
            value += 0.5 * f.step_mm * (1.0 + math.tanh((x_mm - f.step_at_mm) / f.step_width_mm))
        if f.noise_sd_mm > 0:
            value += f.noise_sd_mm * float(self._rng.standard_normal())
        if t_s >= self._next_spike_s:
            self._next_spike_s = self._after(t_s, f.spikes_per_s)
            self.spikes += 1
            value += f.spike_mm * (1.0 if self._rng.random() < 0.5 else -1.0)
        return value


class SensorFaultReadings:
    """N faulty sensors' readings at once, one per valve of the batch path (:mod:`edc_bench.population.batch`).

    The same formula and events as :class:`FaultySensorReading` (its module docstring), on arrays; the noise and
    the events' times come from streams of their own per valve (as the batch's noise is the loop's model, not its
    stream). A sound sensor among them reads the rack as it is.

    Parameters
    ----------
    faults : sequence of SensorFault
        One per valve.
    stroke_mm : float
        The rack's stroke.
    seeds : sequence of int
        One per valve: the seed of its noise and of its dropouts' and spikes' times.
    block : int
        Noise drawn this many readings ahead per valve.
    """

    def __init__(self, faults: Sequence[SensorFault], stroke_mm: float, seeds: Sequence[int],
                 block: int = 1000) -> None:
        if len(faults) != len(seeds):
            raise ValueError("one seed per sensor")
        self._stroke_mm = stroke_mm
        # one array per field of SensorFault, a value per sensor
        self._f = types.SimpleNamespace(**{f.name: np.array([getattr(fault, f.name) for fault in faults], dtype=float)
                                           for f in fields(SensorFault)})
        n = len(faults)
        self._rngs = [np.random.default_rng([seed, 0x5E45]) for seed in seeds]
        self._noise_rngs = [np.random.default_rng([seed, 0x5E46]) for seed in seeds]
        self._block = block
        self._noise = np.zeros((block, n))
        self._row = np.full(n, block)  # each valve's next noise row; ``block``: draw its column again
        self._dropout_until_s = np.full(n, -math.inf)
        self._next_dropout_s = np.array([self._after(j, 0.0, "dropouts_per_s") for j in range(n)])
        self._next_spike_s = np.array([self._after(j, 0.0, "spikes_per_s") for j in range(n)])
        self.dropouts = np.zeros(n, dtype=np.int64)
        self.spikes = np.zeros(n, dtype=np.int64)

    def _after(self, j: int, t_s: float, rate_key: str) -> float:
        rate = getattr(self._f, rate_key)[j]
        return t_s + float(self._rngs[j].exponential(1.0 / rate)) if rate > 0 else math.inf

    def take(self, keep: np.ndarray) -> None:
        """Keep the sensors ``keep`` (indices) only: each keeps its own streams."""
        self._f = types.SimpleNamespace(**{key: values[keep] for key, values in vars(self._f).items()})
        self._rngs = [self._rngs[j] for j in keep]
        self._noise_rngs = [self._noise_rngs[j] for j in keep]
        self._noise = np.ascontiguousarray(self._noise[:, keep])
        for name in ("_row", "_dropout_until_s", "_next_dropout_s", "_next_spike_s", "dropouts", "spikes"):
            setattr(self, name, getattr(self, name)[keep])

    def _noise_of(self, idx: np.ndarray) -> np.ndarray:
        for j in idx[self._row[idx] >= self._block]:
            self._noise[:, j] = self._noise_rngs[j].standard_normal(self._block)
            self._row[j] = 0
        value = self._noise[self._row[idx], idx]
        self._row[idx] += 1
        return value

    def read(self, x_mm: np.ndarray, t_s: float, valves: np.ndarray | None = None) -> np.ndarray:
        """The sensors' signals (mm) for racks at ``x_mm`` at time ``t_s``: of every sensor, or of ``valves``
        (indices) only, ``x_mm`` then theirs."""
        idx = np.arange(len(self._row)) if valves is None else np.asarray(valves)
        f = self._f if valves is None else \
            types.SimpleNamespace(**{key: values[idx] for key, values in vars(self._f).items()})
        due = idx[t_s >= self._next_dropout_s[idx]]
        for j in due:
            self._dropout_until_s[j] = t_s + self._f.dropout_ms[j] * 1e-3
            self._next_dropout_s[j] = self._after(j, t_s, "dropouts_per_s")
            self.dropouts[j] += 1
        u = x_mm / self._stroke_mm
        value = f.gain * x_mm + f.offset_mm + f.bow_mm * 4.0 * u * (1.0 - u)
        value += 0.5 * f.step_mm * (1.0 + np.tanh((x_mm - f.step_at_mm) / f.step_width_mm))
        reading = ~(t_s < self._dropout_until_s[idx])  # a sensor whose contact is open reads its zero
        noisy = (f.noise_sd_mm > 0) & reading
        if noisy.any():
            value[noisy] += f.noise_sd_mm[noisy] * self._noise_of(idx[noisy])
        for m in np.nonzero(reading & (t_s >= self._next_spike_s[idx]))[0]:
            j = idx[m]
            self._next_spike_s[j] = self._after(j, t_s, "spikes_per_s")
            self.spikes[j] += 1
            value[m] += self._f.spike_mm[j] * (1.0 if self._rngs[j].random() < 0.5 else -1.0)
        return np.where(reading, value, 0.0)


#: Each key: (what it is, lowest, highest): generous but physical.
RACK_KEYS: dict[str, tuple[str, float, float]] = {
    "drag_n": ("Coulomb friction added along the stroke, N", 0.0, 10.0),
    "drag_damping_n_s_per_mm": ("viscous drag added along the stroke, N s/mm", 0.0, 0.2),
    "bind_n": ("friction added at one place, N", 0.0, 20.0),
    "bind_at_mm": ("where the bind is, mm from the stop", 0.0, 30.0),
    "bind_width_mm": ("the bind's half width, mm", 0.1, 10.0),
    "slope_n_per_mm": ("friction rising along the stroke, N per mm", -0.2, 0.2),
    "spring_rel": ("the return spring's rate off the pump type's, relative", -0.3, 0.3),
    "preload_rel": ("the return spring's preload off the pump type's, relative", -0.5, 0.5),
}
SENSOR_KEYS: dict[str, tuple[str, float, float]] = {
    "gain": ("the reading's scale, 1 for none", 0.5, 1.5),
    "offset_mm": ("the reading's zero shift, mm", -2.0, 2.0),
    "bow_mm": ("the reading's bow at mid-stroke, mm", -2.0, 2.0),
    "step_mm": ("the reading's local step, mm", -2.0, 2.0),
    "step_at_mm": ("where the step is, mm from the stop", 0.0, 30.0),
    "step_width_mm": ("the step's half width, mm", 0.2, 10.0),
    "noise_sd_mm": ("noise added to each reading, mm", 0.0, 0.5),
    "dropouts_per_s": ("contact dropouts a second", 0.0, 50.0),
    "dropout_ms": ("each dropout's length, ms", 0.5, 20.0),
    "spikes_per_s": ("spikes a second", 0.0, 100.0),
    "spike_mm": ("each spike's size, mm", 0.0, 5.0),
}
#: Named faults, each a starting point that key=value pairs may refine (``bind,bind_n=2``).
RACK_PRESETS: dict[str, RackFault] = {
    "drag": RackFault(drag_n=0.35, drag_damping_n_s_per_mm=0.004),
    "dry": RackFault(drag_n=0.17),
    "bind": RackFault(bind_n=1.0, bind_at_mm=12.0, bind_width_mm=1.0),
    "bent": RackFault(bind_n=3.0, bind_at_mm=11.0, bind_width_mm=2.5),
    "slope": RackFault(slope_n_per_mm=0.013),
}
SENSOR_PRESETS: dict[str, SensorFault] = {
    "long": SensorFault(gain=1.08),
    "zero": SensorFault(offset_mm=0.3),
    "bow": SensorFault(bow_mm=0.3),
    "kink": SensorFault(step_mm=0.3, step_at_mm=12.0, step_width_mm=1.0),
    "noisy": SensorFault(noise_sd_mm=0.02),
    "dropouts": SensorFault(dropouts_per_s=1.0),
    "spikes": SensorFault(spikes_per_s=2.0),
}

_Fault = TypeVar("_Fault", RackFault, SensorFault)


def _spec_of(fault: RackFault | SensorFault, default: RackFault | SensorFault) -> str:
    parts = [f"{f.name}={getattr(fault, f.name):g}" for f in fields(fault)
             if getattr(fault, f.name) != getattr(default, f.name)]
    return ",".join(parts) or "none"


def _parse(text: str, flag: str, kind: type[_Fault], keys: dict[str, tuple[str, float, float]],
           presets: dict[str, _Fault]) -> _Fault:
    given = f"{flag} {text!r}" if flag else repr(text)
    example = f"{', '.join(presets)}, or key=value pairs (keys: {', '.join(keys)})"
    text = text.strip()
    if text in ("", "none"):
        return kind()
    base: _Fault = kind()
    values: dict[str, float] = {}
    for index, part in enumerate(p.strip() for p in text.split(",")):
        key, sep, raw = (s.strip() for s in part.partition("="))
        if not sep:
            if index == 0 and part in presets:
                base = presets[part]
                continue
            what = given if part == text else f"{given}: {part!r}"
            raise ConfigError(f"{what} is not a fault; give {example}")
        if key not in keys:
            raise ConfigError(f"{given}: unknown key {key!r}; give {example}")
        values[key] = pair_value(given, key, raw, values, keys)
    return dataclasses.replace(base, **values)


def parse_rack_fault(text: str, flag: str = "--rack-fault") -> RackFault:
    """``--rack-fault``: ``none``, a preset (:data:`RACK_PRESETS`) and/or ``key=value`` pairs (:data:`RACK_KEYS`).

    Raises
    ------
    ConfigError
        One line naming what is wrong and what to give instead.
    """
    return _parse(text, flag, RackFault, RACK_KEYS, RACK_PRESETS)


def parse_sensor_fault(text: str, flag: str = "--sensor-fault") -> SensorFault:
    """``--sensor-fault``: ``none``, a preset (:data:`SENSOR_PRESETS`) and/or ``key=value`` pairs
    (:data:`SENSOR_KEYS`).

    Raises
    ------
    ConfigError
        One line naming what is wrong and what to give instead.
    """
    return _parse(text, flag, SensorFault, SENSOR_KEYS, SENSOR_PRESETS)
