"""Many bench tests at once: the simulated test vectorised across valves.

The same physics and the same controller as the full loop (docs/bench-test.md) run
on numpy arrays, one element per valve, without the CAN round trip, the
codec or the rig firmware: at tick k the controller uses the rack sampled at
tick k-1, the sample at tick k is taken before the new drive is applied, the
drive is held for one period. The plant steps exactly (matrix exponential per
valve); valves whose velocity reverses or that are stuck are replayed in
0.1 ms quanta with the same Karnopp rule as :class:`~edc_bench.sim.plant.Plant`.
Sensor noise is drawn from the same model but not the same stream, so a
valve's identified parameters agree with the full loop's within the noise;
``tests/population/test_batch.py`` checks the agreement.

This is what makes populations of thousands of valves cheap enough to train
and evaluate a classifier on.
"""

from __future__ import annotations

import math
import sys
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import TypeVar

import numpy as np

from edc_bench.config.models import PARAMETER_NAMES, EstimatorKind, Variant
from edc_bench.control import law
from edc_bench.control.coil import CoilEstimator
from edc_bench.control.design import ControllerDesign
from edc_bench.control.estimators import MAX_COVARIANCE_TRACE
from edc_bench.control.reference import compose, compose_position
from edc_bench.engine.replies import max_reply_age_ticks
from edc_bench.identification.analysis import settle_times_s
from edc_bench.identification.period_fit import (
    BlockAccumulator,
    FitSetup,
    PeriodFit,
    accumulate,
    expected_drive_noise_v,
    reference_condition_number,
    rows,
    solve,
)
from edc_bench.identification.trust import Problem, judged_condition_number, trust_problems
from edc_bench.physics.coil import (
    referred_from_estimate,
    resistance_at_ohm,
    temperature_after_c,
)
from edc_bench.physics.feedforward import feedforward_truth, inductive_shares
from edc_bench.physics.matrix_exponential import expm
from edc_bench.physics.valve import ValveSpec, plant_parameters
from edc_bench.population.batch_link import RING, BatchLink
from edc_bench.population.batch_stop import StopOutcome, BatchStopRule
from edc_bench.sim.kernels import compiled, pump_constants, speed_note
from edc_bench.population.valve_axis import take_last_axis
from edc_bench.sim.adapter import AdapterModel
from edc_bench.sim.plant import STICK_SPEED_MM_S, THERMAL_STEP_S
from edc_bench.sim.pump_faults import RackFault, SensorFault, SensorFaultReadings
from edc_bench.sim.rig import firmware_limits

QUANTA_PER_PERIOD = 10
HISTORY_EVERY = 10  # ticks between stored estimates (settle times at 10 ms resolution)


@dataclass
class BatchResult:
    """Identified parameters of many simulated bench tests.

    Attributes
    ----------
    parameters : numpy.ndarray
        (N, 6) final estimates of a3, a2, a1, a0, b, af.
    truth : numpy.ndarray
        (N, 6) true values from each valve's physics.
    converged : numpy.ndarray
        (N,) at least ``acceptance.min_periods`` periods, each with af and a1 within the settle band.
    settle_s : dict of numpy.ndarray
        Settle times of af and a1 (s after the excitation starts).
    condition_number : float
        Of the period fit's normal equations (the median over the valves).
    reply_age_ticks : dict of int to int
        With an adapter: replies per age (ticks from command to first use), over all valves.
    coil_ohm : numpy.ndarray
        (N,) the coil resistance each test measured last (from drive and current).
    coil_end_ohm : numpy.ndarray
        (N,) the simulated coils' resistance at the end (warmed by the test).
    model_fits : numpy.ndarray
        (N,) the model fits each test (:class:`~edc_bench.identification.analysis.ModelFit`'s limits).
    periods : PeriodResults
        The period fit after any number of periods (what an early-stopped test would have found).
    problems : numpy.ndarray
        (N,) the trust rule's problems per test (:class:`~edc_bench.identification.trust.Problem` bits; 0: trusted).
    stop : StopOutcome or None
        With a stop rule: where each test stopped and what it had found then (the fields above are those figures;
        ``periods`` is None, as a stopped test's later periods do not exist).
    tripped_s : numpy.ndarray
        (N,) when a sample tripped the rig firmware's limits (over-current, the travel limits, the LVDT's range), in s
        from the first tick; NaN where none did. The loop's test aborts there (``problems`` has ABORTED, not
        converged); the batch runs on, its later figures not a test's.

    ``parameters`` and ``truth`` are referred to the reference coil, as the full loop's are.
    """

    parameters: np.ndarray
    truth: np.ndarray
    converged: np.ndarray
    settle_s: dict[str, np.ndarray]
    condition_number: float
    valves: list[ValveSpec]
    seeds: list[int]
    reply_age_ticks: dict[int, int] = field(default_factory=dict)
    coil_ohm: np.ndarray = field(default_factory=lambda: np.zeros(0))
    coil_end_ohm: np.ndarray = field(default_factory=lambda: np.zeros(0))
    model_fits: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=bool))
    periods: PeriodResults | None = None
    problems: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    stop: StopOutcome | None = None
    tripped_s: np.ndarray = field(default_factory=lambda: np.zeros(0))

    @property
    def trusted(self) -> np.ndarray:
        """(N,) the trust rule (:mod:`edc_bench.identification.trust`) finds nothing wrong with the test."""
        return self.problems == 0

    def feature(self, name: str) -> np.ndarray:
        """Column of one parameter, e.g. ``feature("af")``."""
        return self.parameters[:, PARAMETER_NAMES.index(name)]


class _VectorPlant:
    """The plant of N valves (one pump type, different friction and damping; each pump's rack its own)."""

    def __init__(self, variant: Variant, valves: Sequence[ValveSpec], stiction: bool, period_s: float,
                 racks: Sequence[RackFault] | None = None) -> None:
        #: each valve's own physics (the truth its test is held to), and the plant with its pump's rack
        self.valve_params = [plant_parameters(variant, v, stiction=stiction) for v in valves]
        stiction_ratio = variant.valve.stiction_ratio if stiction else 1.0
        params = self.valve_params if racks is None else \
            [rack.applied(p, stiction_ratio) for rack, p in zip(racks, self.valve_params, strict=True)]
        self.params = params
        # the pump type's own parameters (coil, amplifier, stroke, heat) are the same for every valve: read them
        # from the first; each rack's friction along the stroke is in its row of ``_pumps``
        self.pump = params[0]
        n = len(params)
        self.fc = np.array([p.coulomb_friction_n for p in params])
        self.fs = np.array([p.stiction_friction_n for p in params])
        aug = np.zeros((n, 5, 5))
        for j, p in enumerate(params):
            a, b = p.state_matrices()
            aug[j, :3, :3] = a
            aug[j, :3, 3:] = b
        period = expm(aug * period_s)
        quantum = expm(aug * (period_s / QUANTA_PER_PERIOD))
        # coefficients as contiguous rows, so a step indexes no views
        self.phi, self.gam = _coefficients(period)
        self.phi_q, self.gam_q = _coefficients(quantum)
        self._aug = aug
        self._period_s = period_s
        self._tables: tuple[np.ndarray, np.ndarray] | None = None
        self.x = np.zeros(n)
        self.v = np.zeros(n)
        self.i = np.zeros(n)
        self.stuck = np.ones(n, dtype=bool)
        self._pumps = np.array([pump_constants(p.linear, p.preload_n, p.stribeck_velocity_mm_s,
                                               p.force_constant_n_per_a, p.force_constant_slope_per_mm,
                                               p.force_constant_mid_mm, p.net_stiffness_n_per_mm, p.stroke_mm,
                                               STICK_SPEED_MM_S, p.rack_bind_n, p.rack_bind_at_mm,
                                               p.rack_bind_width_mm, p.rack_friction_slope_n_per_mm)
                                for p in params])
        self._every = np.zeros(0, dtype=np.int64)
        # the coil warms as in :class:`~edc_bench.sim.plant.Plant`: stepped every THERMAL_STEP_S
        self.temp_c = np.array([p.coil_temp_c for p in params])
        self.resistance_ohm = np.array([p.resistance_ohm for p in params])
        self._r20 = np.array([p.resistance_20c_ohm for p in params])
        self._heat_j = np.zeros(n)
        self._heat_s = 0.0

    def take(self, keep: np.ndarray) -> None:
        """Keep the valves ``keep`` (indices) only: the others' tests have stopped."""
        self.params = [self.params[j] for j in keep]
        self.valve_params = [self.valve_params[j] for j in keep]
        self._pumps = np.ascontiguousarray(self._pumps[keep])
        take_last_axis(self, keep, ("fc", "fs", "phi", "gam", "phi_q", "gam_q", "x", "v", "i", "stuck", "temp_c",
                                    "resistance_ohm", "_r20", "_heat_j"))
        self._aug = self._aug[keep]
        if self._tables is not None:
            self._tables = (self._tables[0][..., keep], self._tables[1][..., keep])

    def add_heat(self, dt_s: float) -> None:
        """The coils dissipated R i^2 for ``dt_s``; every THERMAL_STEP_S, step their temperature and resistance."""
        compiled().dissipate(self._heat_j, self.resistance_ohm, self.i, dt_s)
        self._heat_s += dt_s
        if self._heat_s < THERMAL_STEP_S - 1e-9:
            return
        p = self.pump
        self.temp_c = temperature_after_c(self.temp_c, self._heat_j / self._heat_s, self._heat_s, p.ambient_c,
                                          p.thermal_capacity_j_per_k, p.thermal_resistance_k_per_w)
        self._heat_j[:] = 0.0
        self._heat_s = 0.0
        if p.temperature_coefficient_per_k == 0.0:
            return
        self.resistance_ohm = resistance_at_ohm(self._r20, self.temp_c, p.temperature_coefficient_per_k)
        self._aug[:, 2, 2] = -self.resistance_ohm / p.inductance_h
        self.phi, self.gam = _coefficients(expm(self._aug * self._period_s))
        self.phi_q, self.gam_q = _coefficients(expm(self._aug * (self._period_s / QUANTA_PER_PERIOD)))
        self._tables = None

    def advance_period(self, drive_v: np.ndarray) -> None:
        """Every valve's plant over one period under its drive (compiled: :mod:`~edc_bench.sim.kernels`)."""
        coil_v = self.pump.amplifier_gain * law.ARRAYS.clip(drive_v, self.pump.amplifier_limit_v)
        n = len(self.x)
        if len(self._every) != n:  # the whole batch, each valve a whole period (rebuilt as valves leave)
            self._every = np.arange(n)
            self._whole_period = np.full(n, QUANTA_PER_PERIOD)
            self._period_dt = np.full(n, self._period_s)
        compiled().advance(self._every, self._whole_period, self.phi, self.gam, self._period_dt, self.x, self.v,
                           self.i, self.stuck, self.phi_q, self.gam_q, coil_v, self.fc, self.fs,
                           self._period_s / QUANTA_PER_PERIOD, self._pumps)

    def advance_quanta(self, quanta: np.ndarray, drive_v: np.ndarray) -> None:
        """Advance each valve by its own number of quanta (0..QUANTA_PER_PERIOD) under a constant drive.

        Used when a CAN adapter makes the drive change mid-period (:mod:`edc_bench.population.batch_link`).
        """
        if self._tables is None:
            # Phi and Gamma of m quanta, m = 0..QUANTA_PER_PERIOD, indexed [m, coefficient, valve]
            q_s = self._period_s / QUANTA_PER_PERIOD
            pairs = [_coefficients(expm(self._aug * (m * q_s))) for m in range(QUANTA_PER_PERIOD + 1)]
            self._tables = np.stack([p for p, _ in pairs]), np.stack([g for _, g in pairs])
        moving = np.nonzero(quanta > 0)[0]
        m = quanta[moving]
        phi_t, gam_t = self._tables
        phi, gam = np.ascontiguousarray(phi_t[m, :, moving].T), np.ascontiguousarray(gam_t[m, :, moving].T)
        coil_v = self.pump.amplifier_gain * law.ARRAYS.clip(drive_v[moving], self.pump.amplifier_limit_v)
        compiled().advance(moving, m, phi, gam, m * (self._period_s / QUANTA_PER_PERIOD), self.x, self.v, self.i,
                           self.stuck, self.phi_q, self.gam_q, coil_v, self.fc, self.fs,
                           self._period_s / QUANTA_PER_PERIOD, self._pumps)


def _coefficients(augmented: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rows of Phi (9, n) and Gamma (6, n) from a stack of augmented exponentials (n, 5, 5)."""
    n = len(augmented)
    phi = np.ascontiguousarray(augmented[:, :3, :3].reshape(n, 9).T)
    gam = np.ascontiguousarray(augmented[:, :3, 3:].reshape(n, 6).T)
    return phi, gam


class _Noise:
    """Seeded Gaussian noise in blocks of ticks, one column per valve."""

    def __init__(self, seeds: Sequence[int], sd: float, block: int = 1000) -> None:
        self.rngs = [np.random.default_rng(s) for s in seeds]
        self.sd = sd
        self.block = block
        self._buf = np.zeros((0, len(seeds)))
        self._row = 0

    def take(self, keep: np.ndarray) -> None:
        """Keep the valves ``keep`` (indices) only: each keeps its own stream."""
        self.rngs = [self.rngs[j] for j in keep]
        self._buf = self._buf[:, keep]

    def next(self) -> np.ndarray:
        if self._row >= len(self._buf):
            self._buf = np.column_stack([r.standard_normal(self.block) for r in self.rngs]) * self.sd
            self._row = 0
        row = self._buf[self._row]
        self._row += 1
        return row


class _RowFeeder:
    """Collects each valve's ticks and feeds the period fit in spans (:mod:`edc_bench.identification.period_fit`).

    The loop's trace holds every tick; a batch of hundreds of valves cannot, so the ticks are kept only until the
    span they belong to has been turned into rows, with half a smoothing window on either side. The rows are
    computed by the same function as the loop's, so the identification is the same. A span never crosses a
    period's end: the period is whole in the fit as soon as its last sample is in (the early stop's moment).
    """

    SPAN = 500
    #: Most tests whose rows are made and summed at a time: a span's rows of a thousand tests (tens of MB) would leave
    #: the CPU's cache between numpy's passes over them. Each test's rows and sums are its own, so the figures are the
    #: same, as long as no slice holds a single test of several (numpy sums a lone column pairwise, in another order
    #: than the columns of a wider one): the slices are even, none narrower than half this.
    TESTS_AT_A_TIME = 64

    def __init__(self, setup: FitSetup, acc: BlockAccumulator, n: int, lag: int) -> None:
        self.setup, self.acc, self.half = setup, acc, setup.window // 2
        cap = self.SPAN + 2 * self.half + 2 + lag
        self.x, self.u, self.rho, self.r1 = (np.zeros((cap, n)) for _ in range(4))
        self.valid = np.zeros((cap, n), dtype=bool)
        self.base = setup.first_tick - self.half  # the tick of row 0
        self.p = setup.first_tick  # the first tick of the next span
        self._cut = self._next_cut()  # the tick after the next span

    def tick(self, k: int, drive_v: np.ndarray, rho: np.ndarray, r1: np.ndarray) -> None:
        """What tick ``k`` sent and used."""
        row = k - self.base
        if 0 <= row:
            self.u[row], self.rho[row], self.r1[row] = drive_v, rho, r1

    def sample(self, j: int, position_mm: np.ndarray, valid: np.ndarray | bool = True) -> int:
        """The sample of tick ``j``'s command (taken before its drive applied); a span is fed once its last is in.

        Returns the number of whole periods in the fit when this sample completed one, else 0.
        """
        row = j - self.base
        if row < 0:
            return 0
        self.x[row], self.valid[row] = position_mm, valid
        if j != self._cut + self.half:
            return 0
        self._feed(self._cut - self.p)
        self._cut = self._next_cut()
        setup = self.setup
        whole, within = divmod(self.p - setup.first_tick, setup.block_ticks)
        return whole if within == 0 else 0

    def _next_cut(self) -> int:
        """Where the next span ends: :attr:`SPAN` ticks on, or the end of the period it is in."""
        setup = self.setup
        period_end = setup.first_tick + ((self.p - setup.first_tick) // setup.block_ticks + 1) * setup.block_ticks
        return min(self.p + self.SPAN, period_end)

    def take(self, keep: np.ndarray) -> None:
        """Keep the valves ``keep`` (indices) only."""
        take_last_axis(self, keep, ("x", "u", "rho", "r1", "valid"))

    def _feed(self, span: int) -> None:
        if span <= 0:
            return
        rows_ = span + 2 * self.half + 1
        n = self.x.shape[1]
        parts = -(-n // self.TESTS_AT_A_TIME)
        for part in range(parts):
            tests = slice(part * n // parts, (part + 1) * n // parts)
            X, y, use, core = rows(self.setup, self.x[:rows_, tests], self.u[:rows_, tests],
                                   self.rho[:rows_, tests], self.r1[:rows_, tests], self.valid[:rows_, tests])
            accumulate(self.setup, self.acc, self.p - self.half, X, y, use, core, tests)
        keep_from = span  # the next span needs from its first tick - half on
        for a in (self.x, self.u, self.rho, self.r1, self.valid):
            a[: len(a) - keep_from] = a[keep_from:]
        self.base += keep_from
        self.p += span

    def finish(self, last_tick: int) -> None:
        """Feed the last, partial span (ticks up to ``last_tick``, the last with a sample and half a window after)."""
        self._feed(last_tick - self.half - self.p)


class _Sensors:
    """The rig's LVDT and current sensor for N valves: the plant's true values, noise from a stream per valve,
    offset and resolution, as the simulated rig's sensors give them."""

    def __init__(self, variant: Variant, plant: _VectorPlant, seeds: Sequence[int], sensor_noise: bool,
                 faults: Sequence[SensorFault] | None = None) -> None:
        lvdt, current = variant.sensors.lvdt, variant.sensors.current
        self.plant = plant
        #: the pumps' rack-travel sensors where one misreads (:mod:`edc_bench.sim.pump_faults`), and the time of the
        #: tick being sampled (the loop sets it: a dropout or a spike comes at a time)
        self.faults = None if faults is None or all(f.none for f in faults) else \
            SensorFaultReadings(faults, variant.rack.stroke_mm, seeds)
        self.t_s = 0.0
        self.noise = _Noise(seeds, lvdt.noise_sd if sensor_noise else 0.0)
        self._resolution = lvdt.resolution if sensor_noise else 1e-9
        self._offset = lvdt.offset if sensor_noise else 0.0
        # the coil current, read with each sample (at the tick, before its drive applies), noise of its own
        self._current_noise = _Noise([s + 7_919 for s in seeds], current.noise_sd if sensor_noise else 0.0)
        self._current_step = current.resolution if sensor_noise else 1e-9
        self._current_offset = current.offset if sensor_noise else 0.0

    def take(self, keep: np.ndarray) -> None:
        """Keep the valves ``keep`` (indices) only."""
        self.noise.take(keep)
        self._current_noise.take(keep)
        if self.faults is not None:
            self.faults.take(keep)

    def read(self, true_mm: np.ndarray, noise_mm: np.ndarray, valves: np.ndarray | None = None) -> np.ndarray:
        """The LVDT's reading of rack positions ``true_mm`` with the given noise (of every valve, or of ``valves``
        only): the pump's sensor's signal, through the rig's conditioning."""
        signal_mm = true_mm if self.faults is None else self.faults.read(true_mm, self.t_s, valves)
        return compiled().quantised_reading(signal_mm, self._offset, noise_mm, self._resolution)

    def sample(self) -> np.ndarray:
        """The rack position now, as the LVDT reads it."""
        return self.read(self.plant.x, self.noise.next())

    def current(self) -> np.ndarray:
        """The coil current now, as the current sensor reads it."""
        return compiled().quantised_reading(self.plant.i, self._current_offset, self._current_noise.next(),
                                            self._current_step)


class _Reference:
    """Each valve's reference, by the loop's arithmetic: its shape at every tick (the same for every start) tabulated
    once, at the times the loop's controller tabulates it, and composed with each valve's start tick by tick
    (:func:`~edc_bench.control.reference.compose`), so a valve's reference is the loop's to the bit for the same
    start."""

    def __init__(self, design: ControllerDesign, start: np.ndarray) -> None:
        reference = design.reference(0.0)
        k = np.arange(design.ticks, dtype=float)  # the times of fel.reference_table
        self._mid_shape = reference.shape((k + 0.5) * design.period_s)
        self._now_shape = reference.shape(k * design.period_s)
        self._mid_mm, self._move_s = reference.mid_mm, reference.move_s
        self.start = start

    def take(self, keep: np.ndarray) -> None:
        """Keep the valves ``keep`` (indices) only."""
        self.start = self.start[keep]

    def at_mid_tick(self, k: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The reference and its first three derivatives in the middle of tick ``k``'s interval (where the drive is
        held), per valve."""
        return compose(self.start, self._mid_mm, self._move_s, self._mid_shape.at(k))

    def now(self, k: int) -> np.ndarray:
        """The reference at tick ``k``'s time, per valve."""
        return compose_position(self.start, self._mid_mm, self._now_shape.at(k))

    def of_ticks(self, ticks: np.ndarray, valves: np.ndarray) -> np.ndarray:
        """The reference at the given ticks for the given valves (tick -1: the start)."""
        start = self.start[valves]
        at = compose_position(start, self._mid_mm, self._now_shape.at(np.maximum(ticks, 0)))  # type: ignore[arg-type]
        return np.where(ticks >= 0, at, start)


class _Controller:
    """The bench controller of N valves: :class:`~edc_bench.control.fel.FelController`'s tick over arrays, by the
    same arithmetic (:mod:`edc_bench.control.law` with :data:`~edc_bench.control.law.ARRAYS`)."""

    def __init__(self, design: ControllerDesign, reference: _Reference, n: int, r_ref: float) -> None:
        self.design, self.reference, self.r_ref = design, reference, r_ref
        self.composition = design.composition()
        # valves along the last axis: every update is a contiguous pass over n values
        self.theta = np.tile(np.array(design.theta0)[:, None], (1, n))
        self.P = np.tile(np.diag(np.array(design.prior_std) ** 2)[:, :, None], (1, 1, n))
        self.gain_vec = (np.array(design.gradient_gains_per_s) * design.period_s)[:, None]
        self.pid_c = law.PidCoefficients.of(design.pid_gains, design.period_s, design.drive_limit_v)
        self.pid = law.PidState(np.zeros(n))
        self.saturated = np.zeros(n)
        self.coil = CoilEstimator(design.amplifier_gain, np.full(n, r_ref), design.period_s)
        self.coil_average = law.CoilAverage(design.coil_window_ticks, np.full(n, r_ref))

    def take(self, keep: np.ndarray) -> None:
        """Keep the valves ``keep`` (indices) only."""
        take_last_axis(self, keep, ("theta", "P", "saturated"))
        self.pid.take(keep)
        self.coil.take(keep)
        self.coil_average.take(keep)
        self.reference.take(keep)

    def step(self, k: int, error_mm: np.ndarray,
             usable: np.ndarray | bool) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Tick ``k``: the drive per valve, the coil ratio it was scaled by, and r' (for the fit's rows)."""
        ops, design = law.ARRAYS, self.design
        rho = self.coil_average.add(self.coil.resistance_ohm) / self.r_ref
        u2 = law.pid_update(ops, self.pid_c, self.pid, error_mm, self.saturated, usable)
        w_all = np.empty((6, len(error_mm)))  # a row per regressor
        law.regressors(ops, w_all, *self.reference.at_mid_tick(k))
        _, u, self.saturated, adapting, w_est, fixed_part = law.feedforward_tick(
            ops, self.composition, self.theta, w_all, u2, rho, k * design.period_s)
        r1 = w_all[2]
        if adapting.any():
            y = law.estimator_target(u, rho, fixed_part)
            if design.estimator_kind is EstimatorKind.RLS:
                law.rls_update(ops, self.theta, self.P, w_est, y, design.forgetting_factor, MAX_COVARIANCE_TRACE,
                               adapting)
            else:
                law.gradient_update(ops, self.theta, self.gain_vec, w_est, y, adapting)
        return u, rho, r1


_speed_said = False


def _say_speed_once() -> None:
    """Say once per process when the batch path runs slower here (:func:`~edc_bench.sim.kernels.speed_note`)."""
    global _speed_said
    note = speed_note()
    if note is not None and not _speed_said:
        _speed_said = True
        print(f"edc-bench: note: {note}", file=sys.stderr)


def run_batch(variant: Variant, valves: Sequence[ValveSpec], seeds: Sequence[int], *, stiction: bool = True,
              sensor_noise: bool = True, adapter: AdapterModel | None = None,
              stop: BatchStopRule | None = None, rack_faults: RackFault | Sequence[RackFault] | None = None,
              sensor_faults: SensorFault | Sequence[SensorFault] | None = None) -> BatchResult:
    """Run one simulated bench test per valve, vectorised.

    Parameters
    ----------
    variant : Variant
        Pump variant (the same for all valves).
    valves : sequence of ValveSpec
        One per test.
    seeds : sequence of int
        Sensor-noise seed per test.
    stiction, sensor_noise : bool
        As in :func:`edc_bench.bench.run_simulated_test`.
    adapter : AdapterModel, optional
        A CAN adapter between bench and rig (:mod:`edc_bench.population.batch_link`): commands take effect and
        samples are taken when it delivers them, and the PID uses the newest sample young enough
        (``acceptance.max_reply_age_ms``), holding its output otherwise. Instant by default.
    stop : BatchStopRule, optional
        The bench's early stop (:mod:`edc_bench.population.batch_stop`): each test ends after the period where the
        loop's would, and the result holds what it had found then (``BatchResult.stop``; no ``periods``). By
        default every test runs its full length.
    rack_faults, sensor_faults : RackFault or SensorFault, or a sequence of them, optional
        The pumps' control racks and rack-travel sensors (:mod:`edc_bench.sim.pump_faults`, as ``--rack-fault`` and
        ``--sensor-fault`` give the simulated rig): one for every valve, or one per valve. Sound by default. The
        truth (``BatchResult.truth``) stays each valve's own: what a faulty rack or sensor makes of it is what the
        test identifies.

    Returns
    -------
    BatchResult
    """
    n = len(valves)
    if n == 0 or len(seeds) != n:
        raise ValueError("one seed per valve, and at least one valve")
    racks, sensors = _per_valve(rack_faults, n, "rack_faults"), _per_valve(sensor_faults, n, "sensor_faults")
    _say_speed_once()
    design = ControllerDesign.from_variant(variant)
    plant = _VectorPlant(variant, valves, stiction, design.period_s, racks)
    run = _prepared(variant, design, plant, _Sensors(variant, plant, seeds, sensor_noise, sensors), seeds, adapter,
                    stop)
    run.all_ticks(run.feeder.setup)
    return run.result(variant, valves, seeds)


_Part = TypeVar("_Part", RackFault, SensorFault)


def _per_valve(faults: _Part | Sequence[_Part] | None, n: int, name: str) -> list[_Part] | None:
    """One fault for every valve, or one per valve, as a list; None where every part is sound."""
    if faults is None:
        return None
    given = [faults] * n if isinstance(faults, (RackFault, SensorFault)) else list(faults)
    if len(given) != n:
        raise ValueError(f"{name}: one per valve ({n}), or one for all; got {len(given)}")
    return None if all(f.none for f in given) else given


def _prepared(variant: Variant, design: ControllerDesign, plant: _VectorPlant, sensors: _Sensors,
              seeds: Sequence[int], adapter: AdapterModel | None, stop: BatchStopRule | None) -> _BatchRun:
    """The batch's ticks set up over ``plant`` and ``sensors`` (a test's own stand-ins may take their place)."""
    n = len(seeds)
    reference = _Reference(design, sensors.sample())  # the SAFE reply before the first tick
    controller = _Controller(design, reference, n, variant.coil.resistance_ohm)
    link = None if adapter is None or adapter.is_instant else BatchLink(
        adapter, seeds, design.period_s, QUANTA_PER_PERIOD, max_reply_age_ticks(variant), reference.of_ticks)
    # the identification the verdict rests on: the period fit, fed the same rows as the loop's trace gives it
    setup = FitSetup.from_variant(variant)
    blocks = setup.blocks_in(design.ticks)
    fit_acc = BlockAccumulator(setup, max(blocks, 1), n)
    lag = 0 if link is None else RING - 2  # through an adapter, command j's sample is read from the link later
    coil_at_blocks = np.full((max(blocks, 1) + 1, n), controller.r_ref)
    periods = PeriodResults(variant, setup, fit_acc, blocks, coil_at_blocks, np.array(design.nominal), controller.r_ref)
    return _BatchRun(design, plant, sensors, controller, link, _RowFeeder(setup, fit_acc, n, lag), lag, periods,
                     stop)


class _BatchRun:
    """The ticks of a batch: the controller's step, the rig's reply and period, what the fit and the history keep,
    and (with a stop rule) the valves whose tests end."""

    def __init__(self, design: ControllerDesign, plant: _VectorPlant, sensors: _Sensors, controller: _Controller,
                 link: BatchLink | None, feeder: _RowFeeder, lag: int, periods: PeriodResults,
                 stop: BatchStopRule | None) -> None:
        self.design, self.plant, self.sensors, self.controller = design, plant, sensors, controller
        self.reference = controller.reference
        self.link, self.feeder, self.lag, self.periods = link, feeder, lag, periods
        self.valve_plants = list(plant.valve_params)  # every valve's own physics, as the plant drops those that stop
        n = len(self.reference.start)
        self.history = np.zeros((design.ticks // HISTORY_EVERY + 1, 2, n))
        self.hist_rows = 0
        est_idx = list(controller.composition.estimated)
        self._h_af = est_idx.index(PARAMETER_NAMES.index("af"))
        self._h_a1 = est_idx.index(PARAMETER_NAMES.index("a1"))
        self._r_prev = self.reference.start.copy()  # the reference at the previous tick (r(0) = start)
        self._x_meas = self.reference.start  # the newest sample (instant link)
        # the coil current sampled at the last tick, used from this one (as the loop does); the drive in effect
        # while it came; the last drive
        self._pending_current: np.ndarray | None = None
        self._u_before = self._u_last = np.zeros(n)
        self.alive = np.arange(n)  # the valves still running, by their place in the batch
        self.stop_rule, self.stopped = stop, StopOutcome(n) if stop is not None else None
        self._settle = {name: np.full(n, np.nan) for name in ("af", "a1")}
        # the rig firmware's checks of every sample (firmware_proto.firmware): where one trips, the loop's test
        # aborts there; the batch marks it (a faulty sensor's dropout, a drive that runs away)
        self._limits = firmware_limits(periods.variant)
        self.tripped_s = np.full(n, np.nan)  # by the valve's place in the batch

    def all_ticks(self, setup: FitSetup) -> None:
        """Run every tick of the test (or until every valve has stopped), then feed the fit what is left."""
        design, controller, link, feeder, periods = self.design, self.controller, self.link, self.feeder, self.periods
        ticks, lag, blocks = design.ticks, self.lag, periods.blocks
        # the tick after which a loop's trace holds b whole periods (and the half window that smooths their end)
        block_end_ticks = {setup.end_tick(b): b for b in range(1, blocks + 1)}
        for k in range(ticks):
            if not len(self.alive):
                return
            if self._pending_current is not None:
                controller.coil.update(self._u_before, self._pending_current)
            u, rho, r1 = controller.step(k, *self._error(k))
            # the coil current at this tick, before this drive (through an adapter too: the coil's figure is an
            # average over seconds, where the adapter's milliseconds do not count)
            if k > 0:  # the first tick's current came under no drive of the test's (as in the loop: left out)
                self._pending_current, self._u_before = self.sensors.current(), self._u_last
                self._trip_where(~(np.abs(self._pending_current) <= self._limits.over_current_a), k)
            self._u_last = u
            feeder.tick(k, u, rho, r1)
            if k in block_end_ticks:  # a loop stopped here would refer its parameters to this coil figure
                periods.coil_at_blocks[block_end_ticks[k]] = controller.coil_average.mean
            whole = self._rig_period(k, u)
            if k % HISTORY_EVERY == 0:
                self._keep_history()
            if whole:
                self._periods_done(whole)
        if link is not None:  # the last commands' samples, as far as they reached the rig
            for j in range(max(0, ticks - lag), ticks):
                if len(self.alive):
                    self._periods_done(feeder.sample(j, *link.delivered_sample(j)))
        if not len(self.alive):
            return
        feeder.finish(ticks - 1)
        periods.coil_at_blocks[blocks if blocks else 0] = controller.coil_average.mean
        if self.stop_rule is not None:  # the test's full length without a fit to judge: ends all the same
            self._periods_done(blocks, last=True)

    def _error(self, k: int) -> tuple[np.ndarray, np.ndarray | bool]:
        """The PID's error at tick ``k`` per valve, and where a sample young enough backs it."""
        if self.link is None:
            return self._r_prev - self._x_meas, True  # the error at the sample's time
        # the samples that came back, each against the reference at its command's tick; none: the last error again
        # while the newest is young enough, else the PID holds
        fresh_err, fresh, newest_usable = self.link.fresh_error(k)
        return np.where(fresh, fresh_err, self.controller.pid.last_error_mm), fresh | newest_usable

    def _rig_period(self, k: int, u: np.ndarray) -> int:
        """The rig takes tick ``k``'s drive: it samples, applies it, and one period passes (through the link, when
        it delivers them). Returns the whole periods in the fit when a sample completed one, else 0."""
        plant, sensors, link, feeder = self.plant, self.sensors, self.link, self.feeder
        whole = 0
        sensors.t_s = k * self.design.period_s
        if link is None:
            self._x_meas = sensors.sample()
            self._trip_where(self._outside_travel(self._x_meas), k)
            whole = feeder.sample(k, self._x_meas)
            plant.advance_period(u)
            self._r_prev = self.reference.now(k)
        else:
            link.send(k, u, sensors.noise.next())
            link.advance_period(k, plant.advance_quanta, lambda: plant.x, sensors.read)
            if k >= self.lag:
                position_mm, delivered = link.delivered_sample(k - self.lag)
                self._trip_where(delivered & self._outside_travel(position_mm), k)
                whole = feeder.sample(k - self.lag, position_mm, delivered)
        plant.add_heat(self.design.period_s)
        return whole

    def _outside_travel(self, position_mm: np.ndarray) -> np.ndarray:
        """Where a rack sample trips the rig: outside the LVDT's range or the travel limits (NaN too)."""
        lim = self._limits
        return ~((lim.lvdt_min_mm <= position_mm) & (position_mm <= lim.lvdt_max_mm)
                 & (lim.travel_min_mm <= position_mm) & (position_mm <= lim.travel_max_mm))

    def _trip_where(self, tripped: np.ndarray, k: int) -> None:
        """The running valves ``tripped`` (a mask) tripped their rig at tick ``k``, unless they had already."""
        if tripped.any():
            at = self.alive[tripped]
            first = at[np.isnan(self.tripped_s[at])]
            self.tripped_s[first] = k * self.design.period_s

    def _keep_history(self) -> None:
        theta = self.controller.theta
        self.history[self.hist_rows, 0] = theta[self._h_af]
        self.history[self.hist_rows, 1] = theta[self._h_a1]
        self.hist_rows += 1

    def _settle_times_s(self, which: np.ndarray | slice) -> dict[str, np.ndarray]:
        """Settle times of af and a1 in the history so far, for the running valves ``which``."""
        variant, design = self.periods.variant, self.design
        history = self.history[:self.hist_rows]
        t_hist = np.arange(self.hist_rows) * HISTORY_EVERY * design.period_s
        return {name: settle_times_s(t_hist, history[:, row, which], design.adapt_from_s,
                                     variant.acceptance.settle_band_rel)
                for name, row in (("af", 0), ("a1", 1))}

    def _periods_done(self, whole: int, last: bool = False) -> None:
        """``whole`` periods are in the fit: the stop rule decides which tests end here (all, at the last)."""
        periods, rule = self.periods, self.stop_rule
        if rule is None or not whole and not last or whole < min(periods.variant.acceptance.min_periods,
                                                                  periods.blocks):
            return
        at = periods.at(whole)
        decision = rule.decide(whole, last or whole >= periods.blocks, at, periods.noise_v,
                               periods.reference_condition)
        if not decision.stop.any():
            return
        self.stopped.record(self.alive, decision.stop, whole, periods.stop_time_s(whole), decision, at,
                            periods.coil_at_blocks[whole], self.plant.resistance_ohm)
        for name, times in self._settle_times_s(decision.stop).items():
            self._settle[name][self.alive[decision.stop]] = times
        self._take(np.nonzero(~decision.stop)[0])

    def _take(self, keep: np.ndarray) -> None:
        """Run on with the valves ``keep`` (indices among the running ones) only."""
        for part in (self.plant, self.sensors, self.controller, self.feeder, self.periods.acc):
            part.take(keep)
        if self.link is not None:
            self.link.take(keep)
        take_last_axis(self, keep, ("history", "_r_prev", "_x_meas", "_u_before", "_u_last", "alive"))
        self.periods.coil_at_blocks = np.ascontiguousarray(self.periods.coil_at_blocks[:, keep])
        if self._pending_current is not None:
            self._pending_current = self._pending_current[keep]

    def result(self, variant: Variant, valves: Sequence[ValveSpec], seeds: Sequence[int]) -> BatchResult:
        """What the batch found, as a :class:`BatchResult`."""
        plant, controller, link, periods = self.plant, self.controller, self.link, self.periods
        r_ref = controller.r_ref
        truth = np.array([list(feedforward_truth(replace(p, resistance_ohm=r_ref))) for p in self.valve_plants])
        ages = dict(sorted(link.ages.items())) if link is not None else {}
        stopped = self.stopped
        aborted = np.isfinite(self.tripped_s)
        if stopped is not None:
            condition = max(periods.reference_condition, float(np.nanmedian(stopped.condition_number))
                            if np.isfinite(stopped.condition_number).any() else math.inf)
            stopped.aborted(aborted, self.tripped_s)
            return BatchResult(stopped.parameters, truth, stopped.converged, self._settle, condition, list(valves),
                               list(seeds), ages, stopped.coil_ohm, stopped.coil_end_ohm,
                               model_fits=stopped.model_fits, problems=stopped.problems, stop=stopped,
                               tripped_s=self.tripped_s)
        at_end = periods.at(periods.blocks)
        return BatchResult(at_end.parameters, truth, at_end.converged & ~aborted, self._settle_times_s(slice(None)),
                           at_end.condition_number, list(valves), list(seeds), ages,
                           controller.coil_average.mean.copy(), plant.resistance_ohm.copy(),
                           model_fits=at_end.model_fits, periods=periods,
                           problems=np.where(aborted, at_end.problems | int(Problem.ABORTED), at_end.problems),
                           tripped_s=self.tripped_s)


@dataclass
class BatchIdentification:
    """The batch's identification as a test stopped after some periods would have it (arrays over valves)."""

    parameters: np.ndarray
    converged: np.ndarray
    model_fits: np.ndarray
    fit: PeriodFit | None
    condition_number: float
    problems: np.ndarray  # (N,) the trust rule's problems per test (Problem bits; 0: trusted)

    @property
    def trusted(self) -> np.ndarray:
        """(N,) the trust rule finds nothing wrong with the test."""
        return self.problems == 0


class PeriodResults:
    """The period fit of every valve, at any number of periods: a test that stopped then would give these."""

    def __init__(self, variant: Variant, setup: FitSetup, acc: BlockAccumulator, blocks: int,
                 coil_at_blocks: np.ndarray, nominal: np.ndarray, r_ref: float) -> None:
        self.variant, self.setup, self.acc, self.blocks = variant, setup, acc, blocks
        self.coil_at_blocks, self.nominal, self.r_ref = coil_at_blocks, nominal, r_ref
        self.reference_condition = reference_condition_number(ControllerDesign.from_variant(variant))
        self.noise_v = expected_drive_noise_v(variant)

    @property
    def n(self) -> int:
        """The tests the fit holds (fewer once some have stopped)."""
        return self.acc.A.shape[1]

    def stop_time_s(self, periods: int) -> float:
        """When a test has ``periods`` whole periods (and the half smoothing window after them)."""
        return self.setup.end_s(periods)

    def at(self, periods: int) -> BatchIdentification:
        """Parameters (referred to the reference coil), converged and model-fit flags after ``periods`` periods."""
        from edc_bench.identification.analysis import judges_model_fit, model_fits

        acc = self.variant.acceptance
        fit = solve(self.acc, periods, acc.settle_band_rel)
        final = np.tile(self.nominal, (self.n, 1))
        if fit is None:
            nan = np.full(self.n, False)
            final[:, [PARAMETER_NAMES.index(c) for c in ("af", "a1")]] = np.nan
            return BatchIdentification(final, nan, nan, None, math.inf,
                                       np.full(self.n, int(Problem.TOO_FEW_PERIODS | Problem.POORLY_CONDITIONED)))
        inductive = inductive_shares(self.variant)
        coil = self.coil_at_blocks[periods]
        for name in fit.columns:
            if name in PARAMETER_NAMES:
                i = PARAMETER_NAMES.index(name)
                final[:, i] = referred_from_estimate(inductive[i], fit.value(name), self.r_ref, coil)
        enough = periods >= acc.min_periods
        fits = ~judges_model_fit(self.variant, periods, fit) | model_fits(self.variant, fit, self.noise_v)
        converged = fit.settled & enough
        problems = trust_problems(acc, periods=periods, settled=fit.settled, misfit=~fits,
                                  condition_number=judged_condition_number(self.reference_condition,
                                                                           fit.condition_number))
        return BatchIdentification(final, converged, fits, fit, max(self.reference_condition,
                                                                    float(np.median(fit.condition_number))),
                                   problems)
