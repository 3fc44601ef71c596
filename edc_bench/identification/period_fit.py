"""The identification the verdict rests on: least squares over whole excitation periods.

The online estimator (:mod:`edc_bench.control.estimators`) keeps the
feedforward right while the test runs; it regresses on the *reference* with a
memory of about one period. The diagnosis features come from this module
instead (docs/method.md, "The identification the verdict rests on"):

- **On the trajectory the rack followed.** The drive u_k is held from the
  moment the rig takes command k, when it also samples the rack; the
  regressors are the measured rack position smoothed by a Savitzky-Golay
  filter (a local polynomial, ``SMOOTHING_ORDER``, over about an eighth of the
  fastest tone's period) and its derivatives, taken at mid-hold. A lightly
  damped rack rings after every reversal (0.08 mm on the hard variant); a
  regression on the reference takes that ringing for damping (a1 -20 %).
  Smoothing leaves sensor noise at a few per mille of the signal, so it
  biases nothing measurable.
- **Only while the rack slides.** Rows where the reference or the rack moves
  slower than ``reversal_exclusion`` of the peak speed are left out: stick
  windows and breakaway are no part of the sgn(x') model. The estimate
  takes the core rows of these (:func:`core_rows`: the whole smoothing
  window slides), with the gain terms below held at the fit over every
  row's; the model-fit figures are that fit's.
- **With the solenoid's position dependence.** A force constant
  k_i (1 + s (x - x_m)) divides the drive by 1 + s Delta; to first order that
  adds Delta^2, Delta x' and Delta sgn(x') to the regressors (Delta = x - x_m).
  Their coefficients are nuisance parameters; the one of Delta sgn(x') is
  -s af, which gives the force constant's variation over the swing. Of the
  second order, the friction's Delta^2 sgn(x') (s^2 af) is fitted too: left
  to af, it put a1 10-12 % off on pumps whose gain varies +/-20-25 %.
- **In whole periods.** Normal equations are summed per period of the
  excitation (its tones' common period), after a first period in which the
  feedforward learns. The estimate is the least-squares solution over all
  periods; each period's own solution gives the spread from one period to the
  next, hence the uncertainty (standard error of the mean), and the settle
  test (the first half of the periods against the second: no drift).
- **Misfit, apart from noise.** What the model leaves unexplained the same
  way in every period is its misfit; noise (the sensor's, a CAN adapter's
  timing jitter) is not the same twice. Products of each row's residual with
  the residuals of the earlier periods at the same phase measure the first
  without the second (``systematic_rms_v``).

Pure numpy; the loop's trace (:func:`trace_blocks`) and the batch path
(:class:`BlockAccumulator` fed with :func:`rows`) use the same code.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field

import numpy as np

from edc_bench.config.models import PARAMETER_NAMES, Variant
from edc_bench.control.design import ControllerDesign

#: Polynomial order of the smoothing (derivatives up to the third are taken from it).
SMOOTHING_ORDER = 4
#: Ticks either side of a sample whose straight line gives the rack's speed there, for whether a row's window slides
#: (:func:`core_rows`; eleven samples: the LVDT's noise moves the speed by a few per cent of the exclusion's).
SPEED_SPAN_TICKS = 5
#: The model's misfit at reversals in a verdict's interval: this many times the core shift (the fit over every row's
#: distance from the estimate, the core rows' fit: :attr:`PeriodFit.core_shift`). The core rows are not wholly clear
#: of the reversals either (their window's edge, the ringing after a breakaway), so the estimate keeps a share of
#: the shift; docs/method.md, "The interval", prints the coverage this factor gives (``edc-bench evaluate
#: --coverage``).
MISFIT_ALLOWANCE = 2.0
#: The model's misfit away from reversals in a verdict's interval: this many times the repeating residual beyond the
#: baseline's, over each coefficient's term in the drive (:attr:`PeriodFit.term_rms_v`): as if that much of the
#: misfit had gone into the term. A misfit spread over the swing (a solenoid whose gain varies beyond the model's
#: series) moves the core shift little; it shows in the residual's repeating part (docs/method.md, "The interval").
RESIDUAL_ALLOWANCE = 1.0
#: Names of the nuisance terms of the force constant's position dependence (Delta = x - x_m).
GAIN_TERMS = ("d2", "dv", "df", "d2f")  # Delta^2, Delta x', Delta sgn(x'), and of the second order Delta^2 sgn(x')
#: Periods used at least before a test can count as converged (three give a spread with two degrees of freedom).
MIN_PERIODS = 3
#: From this many periods the drift test allows for noise (:func:`drift_free`); with fewer the noise estimate rests
#: on too few differences to tell a drift of a few per cent from noise.
DRIFT_MIN_PERIODS = 8
#: The 99 % quantile of :func:`drift_statistic` on white noise, by periods (Monte Carlo, 400 000 draws each:
#: :func:`edc_bench.experiments.studies.drift_critical_value`; tests/identification/test_period_fit.py checks it).
#: Interpolated between, the last value beyond.
DRIFT_CRITICAL = (
    (8, 5.29), (9, 4.79), (10, 4.49), (11, 4.28), (12, 4.08), (13, 3.93), (14, 3.82), (15, 3.73), (16, 3.62),
    (17, 3.56), (18, 3.47), (19, 3.44), (20, 3.39), (21, 3.36), (22, 3.31), (23, 3.29), (24, 3.26), (25, 3.23),
    (26, 3.22), (27, 3.19), (28, 3.15), (29, 3.13), (30, 3.13), (31, 3.09), (32, 3.08), (40, 2.97), (48, 2.91),
    (64, 2.82), (96, 2.76), (128, 2.71), (192, 2.67), (256, 2.65), (384, 2.62), (512, 2.62),
)


def excitation_period_s(frequencies_hz: list[float]) -> float:
    """The tones' common period (whole periods of every tone), or the slowest tone's period if they have none short.

    >>> excitation_period_s([0.5, 3.0])
    2.0
    """
    slowest = min(frequencies_hz)
    for m in range(1, 9):
        span = m / slowest
        if all(abs(f * span - round(f * span)) < 1e-6 * max(1.0, f * span) for f in frequencies_hz):
            return span
    return 1.0 / slowest


@dataclass(frozen=True)
class FitSetup:
    """Everything the period fit needs from a variant, as numbers.

    Attributes
    ----------
    period_s : float
        Tick period T.
    block_ticks : int
        Ticks of one excitation period (a block).
    first_tick : int
        First tick of the first block: the move, the fade-in and one period of learning (less half a smoothing
        window and a tick) are left out.
    window : int
        Savitzky-Golay window (odd, ticks).
    exclusion_mm_s : float
        Rows where |r'| or |x'| is below this are left out (stick windows).
    mid_mm : float
        x_m, about which the force constant varies.
    estimated, fixed : tuple of int
        Indices into a3..af of the estimated and the fixed parameters.
    nominal : tuple of float
        Nominal a3..af (the fixed ones are taken off the target with them).
    scales : tuple of float
        Column scales of the basis and the gain terms (conditioning only).
    swing_mm : float
        The excitation's amplitude about mid-stroke (sum of the tones').
    """

    period_s: float
    block_ticks: int
    first_tick: int
    window: int
    exclusion_mm_s: float
    mid_mm: float
    estimated: tuple[int, ...]
    fixed: tuple[int, ...]
    nominal: tuple[float, ...]
    scales: tuple[float, ...]
    swing_mm: float

    @classmethod
    def from_variant(cls, variant: Variant) -> FitSetup:
        """The setup of ``variant``'s tests."""
        design = ControllerDesign.from_variant(variant)
        tones = variant.excitation.active_tones
        T = design.period_s
        block_s = excitation_period_s([t.frequency_hz for t in tones])
        fastest_hz = max(t.frequency_hz for t in tones)
        window = max(SMOOTHING_ORDER + 3, int(round(0.125 / fastest_hz / T)))
        window = min(window, 41) | 1  # odd; 41 ms at most (the 3 Hz tone's eighth)
        block_ticks = int(round(block_s / T))
        # one period of learning, less the half window and the sample that complete a block's last rows: so the
        # blocks are in hand when move, fade-in, learning and they have run (3 on the shipped variants: 10.0 s,
        # where 21 ticks more were waited before)
        first = int(round((design.move_s + design.fade_s) / T)) + block_ticks - (window // 2 + 1)
        swing = sum(t.amplitude_mm for t in tones)
        velocity = design.scales[2]
        return cls(period_s=T, block_ticks=block_ticks, first_tick=first, window=window,
                   exclusion_mm_s=design.reversal_speed_mm_s, mid_mm=design.mid_mm, estimated=design.estimated,
                   fixed=design.fixed, nominal=design.nominal,
                   scales=(*design.scales, swing * swing, swing * velocity, swing, swing * swing), swing_mm=swing)

    @property
    def columns(self) -> tuple[str, ...]:
        """Names of the fitted coefficients: the estimated parameters, then :data:`GAIN_TERMS`."""
        return tuple(PARAMETER_NAMES[i] for i in self.estimated) + GAIN_TERMS

    def block_of(self, tick: int) -> int:
        """The block a tick belongs to (negative before the first)."""
        return (tick - self.first_tick) // self.block_ticks if tick >= self.first_tick else -1

    def end_tick(self, blocks: int) -> int:
        """The tick whose sample completes ``blocks`` whole blocks (their last row, the next sample and half a
        smoothing window after it): a test stopped after this tick holds them, and no more."""
        return self.first_tick + blocks * self.block_ticks + self.window // 2

    def end_s(self, blocks: int) -> float:
        """How long a test stopped after :meth:`end_tick` of ``blocks`` lasted (trace time)."""
        return (self.end_tick(blocks) + 1) * self.period_s

    def blocks_in(self, ticks: int) -> int:
        """Complete blocks in ``ticks`` ticks (the inverse of :meth:`end_tick`)."""
        return max(0, (ticks - 1 - self.end_tick(0)) // self.block_ticks)


def _halves_gap(per_period: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The gap between the means of the second and the first half of the periods, and its standard error, with
    the period farthest from the median left out of both (``per_period`` is (periods, ...), periods >= 4)."""
    periods = per_period.shape[0]
    outlier = np.argmax(np.abs(per_period - np.median(per_period, axis=0)), axis=0)
    index = np.arange(periods).reshape((periods,) + (1,) * (per_period.ndim - 1))
    # the kept periods in time order: a stable sort puts the left-out one last
    order = np.argsort(index == outlier, axis=0, kind="stable")[:-1]
    kept = np.take_along_axis(per_period, order, axis=0)
    first = order < periods // 2
    early_n, late_n = first.sum(axis=0), (~first).sum(axis=0)
    gap = np.abs(np.where(first, 0.0, kept).sum(axis=0) / late_n - np.where(first, kept, 0.0).sum(axis=0) / early_n)
    steps = np.sort(np.diff(kept, axis=0) ** 2, axis=0)[:-1]
    variance = np.sum(steps, axis=0) / (2.0 * (periods - 3))
    return gap, np.sqrt(variance * (1.0 / early_n + 1.0 / late_n))


def drift_statistic(per_period: np.ndarray) -> np.ndarray:
    """The gap between the means of the second and the first half of the periods, in standard errors, one
    outlying period aside.

    The period farthest from the median is left out of both halves and of the noise: a CAN adapter's timing
    scatters the periods' estimates with heavier tails than a normal distribution's (docs/method.md, section 7,
    prints the worst single period of 200 `p-edc-hard` valves through usb-fs), and a drift moves many
    periods, not one. The noise is taken from the differences between successive periods, the largest left out
    (von Neumann, trimmed): a drift hardly inflates it (a steady drift of b per period adds about b^2 / 2 to the
    variance, a step nothing), where the scatter about each half's own mean would grow with any drift inside a
    half and let a steady drift of any size pass. ``per_period`` is (periods, ...), periods >= 4.
    """
    gap, standard_error = _halves_gap(per_period)
    with np.errstate(divide="ignore", invalid="ignore"):
        return gap / standard_error


def _nan_mean(values: np.ndarray) -> np.ndarray:
    """np.nanmean over the first axis (the same sums), NaN without a warning where every value is NaN (a test
    without a period of its own: no drift known, and NaN compares False)."""
    finite = ~np.isnan(values)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(finite, values, 0.0).sum(axis=0) / finite.sum(axis=0)


def drift_free(per_period: np.ndarray, estimate: np.ndarray, band_rel: float) -> np.ndarray:
    """Whether a coefficient's estimates, period by period, show no drift.

    The means over the first half of the periods and over the second half must agree within ``band_rel`` of the
    estimate. From :data:`DRIFT_MIN_PERIODS` periods on, one outlying period is left out of them
    (:func:`drift_statistic`), and they may also differ by what the periods' noise explains: their
    :func:`drift_statistic` at most the 99 % quantile it has on white noise (:data:`DRIFT_CRITICAL`), so that a
    test whose estimates merely scatter is called drifting once in a hundred at most.

    Parameters
    ----------
    per_period : numpy.ndarray
        (periods, N) each period's own estimate (NaN where a period had none).
    estimate : numpy.ndarray
        (N,) the estimate over all periods, which the band is relative to.
    band_rel : float
        The settle band (``acceptance.settle_band_rel``).

    Returns
    -------
    numpy.ndarray
        (N,) bool.
    """
    periods = per_period.shape[0]
    if periods < 2:
        return np.ones(per_period.shape[1:], dtype=bool)
    if periods < DRIFT_MIN_PERIODS:
        half = periods // 2
        early, late = _nan_mean(per_period[:half]), _nan_mean(per_period[half:])
        return np.abs(late - early) <= band_rel * np.abs(estimate)
    gap, standard_error = _halves_gap(per_period)
    ns, values = zip(*DRIFT_CRITICAL)
    with np.errstate(divide="ignore", invalid="ignore"):
        noise_only = gap / standard_error <= np.interp(periods, ns, values)
    return (gap <= band_rel * np.abs(estimate)) | noise_only  # NaN compares False


@functools.lru_cache(maxsize=8)
def _smoothing_kernels(window: int, period_s: float) -> np.ndarray:
    """Savitzky-Golay weights for x and its first three derivatives at a window's centre, (4, window).

    ``out[t] = sum_j c[j] x[t + j - h]``: the least-squares polynomial of :data:`SMOOTHING_ORDER` through the
    window's samples, differentiated at its centre (numpy only: scipy.signal would cost a second at every start
    of the command line). Cached: the early stop smooths a short span every tenth of a second. Read only.
    """
    half = window // 2
    j = np.arange(-half, half + 1, dtype=float)
    fit = np.linalg.pinv(np.vander(j, SMOOTHING_ORDER + 1, increasing=True))  # polynomial coefficients from samples
    kernels = np.stack([math.factorial(q) * fit[q] / period_s ** q for q in range(4)])
    kernels.flags.writeable = False
    return kernels


#: Elements of the smoothing's output worked on at a time: a slice of rows small enough to stay in the CPU's cache
#: while the window passes over it (the batch path smooths thousands of valves' spans at once).
_SMOOTH_CHUNK_ELEMENTS = 1 << 15


def _smooth(values: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """Smooth each of Q signals with its own weights: ``values`` (Q, T, ...), ``weights`` (Q, W) -> (Q, T, ...).

    Along the time axis; the ends repeat the first and last sample. One pass over the window for all Q signals:
    a short span costs the same few dozen numpy operations as a long one (the per-element sums are those of
    smoothing each signal alone, in the window's order). The rows are taken a cache-sized slice at a time.
    """
    half = weights.shape[1] // 2
    pad = [(0, 0), (half, half)] + [(0, 0)] * (values.ndim - 2)
    padded = np.pad(np.asarray(values, dtype=float), pad, mode="edge")
    ticks = values.shape[1]
    w = weights.reshape(weights.shape + (1,) * (values.ndim - 2))
    out = np.empty(padded[:, :ticks].shape)
    per_row = max(1, out[:, :1].size)
    step = max(1, _SMOOTH_CHUNK_ELEMENTS // per_row)
    term = np.empty(out[:, :step].shape)
    for t0 in range(0, ticks, step):
        t1 = min(ticks, t0 + step)
        acc, tmp = out[:, t0:t1], term[:, :t1 - t0]
        np.multiply(w[:, 0, None], padded[:, t0:t1], out=acc)
        for j in range(1, weights.shape[1]):
            np.multiply(w[:, j, None], padded[:, t0 + j: t1 + j], out=tmp)
            np.add(acc, tmp, out=acc)
    return out


def rows(setup: FitSetup, position_mm: np.ndarray, drive_v: np.ndarray, rho: np.ndarray,
         reference_velocity_mm_s: np.ndarray,
         valid: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Regressors, target, usable-row mask and the core rows (those clear of any stick) for a span of ticks.

    Parameters
    ----------
    setup : FitSetup
    position_mm : numpy.ndarray
        (T,) or (T, N): the rack sampled when each tick's command took effect.
    drive_v : numpy.ndarray
        The drive of each tick (held until the next).
    rho : numpy.ndarray
        The coil's resistance over the reference coil's, as the loop used it at each tick.
    reference_velocity_mm_s : numpy.ndarray
        r' at mid-tick.
    valid : numpy.ndarray
        False where a tick's own sample is missing (no reply, a gap).

    Returns
    -------
    (X, y, use, core)
        X (T, [N,] p) scaled regressors, y (T, [N]) target, use (T, [N]) the rows to fit: the first and last
        half window of the span are never usable (their smoothing is incomplete); core (T, [N]) the used rows
        whose whole smoothing window slides (:func:`core_rows`), the rows the estimate is fitted to.
    """
    x = np.asarray(position_mm, dtype=float)
    kernels = _smoothing_kernels(setup.window, setup.period_s)
    with np.errstate(invalid="ignore", divide="ignore"):  # a gap's row before any tick holds 0 / 0: not usable
        raw = np.broadcast_to(np.asarray(drive_v, dtype=float) / np.asarray(rho, dtype=float), x.shape)
    # x and its three derivatives, and the drive smoothed as the trajectory is (below), in one pass
    smoothed = _smooth(np.stack([x, x, x, x, raw]), np.concatenate([kernels, kernels[:1]]))
    smooth = list(smoothed[:4])
    # mid-hold: the drive of row k acts from sample k to sample k + 1
    mid = [np.concatenate((0.5 * (s[:-1] + s[1:]), s[-1:]), axis=0) for s in smooth]
    x0, x1, x2, x3 = mid
    sgn = np.sign(x1)
    delta = x0 - setup.mid_mm
    basis = (x3, x2, x1, x0, np.ones_like(x0), sgn)
    # the drive smoothed as the trajectory is, at mid-hold: both sides of the model through the same filter, so the
    # moments a CAN adapter lets each drive take effect (two in one USB frame) average out as they do in the rack
    target = smoothed[4]
    for i in setup.fixed:
        target = target - setup.nominal[i] * basis[i]
    sc = setup.scales
    cols = [basis[i] / sc[i] for i in setup.estimated]
    cols += [delta * delta / sc[6], delta * x1 / sc[7], delta * sgn / sc[8], delta * delta * sgn / sc[9]]
    X = np.stack(cols, axis=-1)
    # a row needs its sample and the next, and every sample the smoothing reaches, to be real
    half = setup.window // 2
    ticks = len(x)
    k = np.arange(ticks)
    hi, lo = np.minimum(k + half + 2, ticks), np.maximum(k - half, 0)  # samples k - half .. k + 1 + half
    near_bad = _any_in(~np.asarray(valid, dtype=bool), lo, hi)
    edge = np.zeros(len(x), dtype=bool)
    edge[half: len(x) - half - 1] = True
    if x.ndim == 2:
        edge = edge[:, None]
    limit = setup.exclusion_mm_s
    sliding = (np.abs(reference_velocity_mm_s) >= limit) & (np.abs(x1) >= limit)
    use = sliding & ~near_bad & edge & np.isfinite(target) & np.all(np.isfinite(X), axis=-1)
    return X, np.where(use, target, 0.0), use, use & core_rows(setup, x, lo, hi)


def core_rows(setup: FitSetup, position_mm: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Rows whose smoothing window (samples ``lo[k] .. hi[k] - 1``) slides at every sample it reaches.

    A row is a weighted sum over its window; one that reaches into a stick or a breakaway smooths their forces
    (stiction, a Stribeck peak) into a row the sgn(x') model reads as sliding, and pulls a1 (the friction's excess
    at a reversal lines up with the speed's fall). The estimate is the fit over these rows; its distance from the
    fit over every row measures what the model misses at reversals (:func:`solve`, ``core_shift``). The rack's
    speed at each sample is the slope of a straight line through the :data:`SPEED_SPAN_TICKS` samples either side
    (fewer when the window is shorter than that), all inside the
    window, so that a row's flag depends on its window alone, however the trace is cut into spans (the early stop
    feeds it a step at a time).
    """
    x = position_mm
    ticks, m = len(x), min(SPEED_SPAN_TICKS, max(1, setup.window // 2))
    slow = np.zeros(x.shape, dtype=bool)
    if ticks > 2 * m:
        with np.errstate(invalid="ignore"):  # a missing sample (NaN) counts as slow; its rows are unusable anyway
            speed = _smooth(x[None], _slope_kernel(m, setup.period_s))[0]
            slow[m:ticks - m] = ~(np.abs(speed[m:ticks - m]) >= setup.exclusion_mm_s)
    return ~_any_in(slow, np.minimum(lo + m, ticks), np.maximum(hi - m, 0))


@functools.lru_cache(maxsize=8)
def _slope_kernel(half: int, period_s: float) -> np.ndarray:
    """Least-squares slope weights over ``2 half + 1`` samples, (1, 2 half + 1): a straight line's speed."""
    j = np.arange(-half, half + 1, dtype=float)
    kernel = (j / (period_s * float(j @ j)))[None]
    kernel.flags.writeable = False
    return kernel


def _any_in(flags: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """For each row k, whether any of ``flags[lo[k]:hi[k]]`` is set (along the first axis; empty: False)."""
    cum = np.concatenate((np.zeros_like(flags[:1], dtype=np.int64), np.cumsum(flags, axis=0)), axis=0)
    return (cum[np.maximum(hi, lo)] - cum[lo]) > 0


class BlockAccumulator:
    """Normal equations per block (excitation period), for one or N tests.

    Beside each block's normal equations it keeps the products of each row with the rows of every earlier
    block at the same phase of the excitation (the same tick of the period): what the model leaves unexplained
    the same way in every period is its misfit; noise (the sensor's, a CAN adapter's timing) is not the same
    twice, and drops out of these products (:func:`solve`, ``systematic_rms_v``).

    Parameters
    ----------
    setup : FitSetup
    blocks : int
        Most blocks a test can have.
    n : int, optional
        Tests side by side (the batch path); 1 for the loop.
    """

    def __init__(self, setup: FitSetup, blocks: int, n: int = 1) -> None:
        p = len(setup.columns)
        self.setup = setup
        self.A = np.zeros((blocks, n, p, p))
        self.z = np.zeros((blocks, n, p))
        self.yy = np.zeros((blocks, n))
        self.count = np.zeros((blocks, n))
        # sums over the rows of block b times the rows of the blocks before it at the same phase (both used):
        # y y', X y' + X' y, X X'^T, and the pairs
        self.pair_yy = np.zeros((blocks, n))
        self.pair_xy = np.zeros((blocks, n, p))
        self.pair_xx = np.zeros((blocks, n, p, p))
        self.pair_count = np.zeros((blocks, n))
        # the normal equations over the core rows alone (clear of any stick: :func:`core_rows`)
        self.A_core = np.zeros((blocks, n, p, p))
        self.z_core = np.zeros((blocks, n, p))
        self.yy_core = np.zeros((blocks, n))
        self.count_core = np.zeros((blocks, n))
        # by phase, over the used rows fed so far: sum of X, of y, and their count. Rows come in time order (a
        # span's unused edge rows aside), so a row of block b finds here the rows of blocks 0..b-1 at its phase
        self._by_phase = np.zeros((setup.block_ticks, n, p + 2))

    def add(self, block: int, X: np.ndarray, y: np.ndarray, use: np.ndarray, phase: int = 0,
            core: np.ndarray | None = None, tests: slice = slice(None)) -> None:
        """Add the rows of one span that all belong to ``block`` (X (T, N, p) or (T, p)), its first row at tick
        ``phase`` of the block. Each row is used in one span only, and the used rows come in time order.
        ``core``: which of the used rows are core rows (:func:`core_rows`; None: all of them). ``tests``: the
        tests (second axis) the rows are of, when they are not all of them (each test's sums are its own); a slice,
        not an index array, as the sums by phase are updated through a view."""
        if X.ndim == 2:
            X, y, use = X[:, None, :], y[:, None], use[:, None]
            core = None if core is None else core[:, None]
        w = use.astype(float)
        Xw = (X * w[..., None]).transpose(1, 2, 0)  # (N, p, T): one batched matrix product per test (BLAS)
        XT = X.transpose(1, 0, 2)
        A, z = Xw @ XT, (Xw @ y.T[..., None])[..., 0]
        self.A[block, tests] += A
        self.z[block, tests] += z
        yy, count = ((y * w) * y).sum(axis=0), w.sum(axis=0)
        if core is None:
            self.A_core[block, tests] += A
            self.z_core[block, tests] += z
            self.yy_core[block, tests] += yy
            self.count_core[block, tests] += count
        else:
            wc = (core & use).astype(float)
            Xc = (X * wc[..., None]).transpose(1, 2, 0)
            self.A_core[block, tests] += Xc @ XT
            self.z_core[block, tests] += (Xc @ y.T[..., None])[..., 0]
            self.yy_core[block, tests] += ((y * wc) * y).sum(axis=0)
            self.count_core[block, tests] += wc.sum(axis=0)
        self.yy[block, tests] += yy
        self.count[block, tests] += count
        p = X.shape[-1]
        earlier = self._by_phase[phase: phase + len(X), tests]
        X0, y0 = earlier[..., :p], earlier[..., p]
        self.pair_yy[block, tests] += (y * w * y0).sum(axis=0)
        self.pair_xy[block, tests] += ((Xw @ y0.T[..., None])[..., 0]
                                       + (X0.transpose(1, 2, 0) @ (w * y).T[..., None])[..., 0])
        self.pair_xx[block, tests] += Xw @ X0.transpose(1, 0, 2)
        self.pair_count[block, tests] += (w * earlier[..., p + 1]).sum(axis=0)
        earlier[..., :p] += X * w[..., None]
        earlier[..., p] += y * w
        earlier[..., p + 1] += w

    #: The per-block sums :meth:`add` changes (first axis: block, second: test).
    _SUMS = ("A", "z", "yy", "count", "pair_yy", "pair_xy", "pair_xx", "pair_count",
             "A_core", "z_core", "yy_core", "count_core")

    def take(self, keep: np.ndarray) -> None:
        """Keep the tests ``keep`` (indices) only: a batch whose other tests have stopped."""
        for name in (*self._SUMS, "_by_phase"):
            setattr(self, name, np.ascontiguousarray(getattr(self, name)[:, keep]))

    def copy(self) -> BlockAccumulator:
        """A copy whose sums are its own: rows added to it leave this one as it is (the early stop's trial fit with a
        period's last rows, whose replies may still come)."""
        out = object.__new__(BlockAccumulator)
        out.__dict__.update(self.__dict__)
        for name in (*self._SUMS, "_by_phase"):
            setattr(out, name, getattr(self, name).copy())
        return out


def accumulate(setup: FitSetup, acc: BlockAccumulator, start: int, X: np.ndarray, y: np.ndarray,
               use: np.ndarray, core: np.ndarray | None = None, tests: slice = slice(None)) -> None:
    """Add rows for ticks ``start .. start + len(X) - 1`` to their blocks (rows before the first block are skipped);
    ``core`` and ``tests`` as :meth:`BlockAccumulator.add` takes them."""
    T = len(X)
    k = max(start, setup.first_tick)
    end = start + T
    while k < end:
        block = setup.block_of(k)
        if block >= len(acc.A):
            return
        block_start = setup.first_tick + block * setup.block_ticks
        block_end = min(end, block_start + setup.block_ticks)
        sl = slice(k - start, block_end - start)
        acc.add(block, X[sl], y[sl], use[sl], phase=k - block_start, core=None if core is None else core[sl],
                tests=tests)
        k = block_end


@dataclass
class PeriodFit:
    """The identification over whole periods, for one or N tests (arrays over tests, or scalars for one).

    Attributes
    ----------
    theta : numpy.ndarray
        ([N,] p) the coefficients in physical units (estimated parameters, then gain terms): the fit over the core
        rows (:func:`core_rows`), with the gain terms of the fit over every row.
    block_theta : numpy.ndarray
        (blocks, [N,] p) each period's own solution.
    std : numpy.ndarray
        ([N,] p) standard error of the mean of the periods (the larger of ``spread_se`` and ``ls_std``).
    blocks : int
        Periods used.
    residual_rms_v : numpy.ndarray
        RMS of what the model leaves unexplained.
    spread_rel : dict
        ``af``, ``a1``: standard deviation of the periods' estimates, relative to the estimate.
    gain_variation_rel : numpy.ndarray
        The force constant's variation over the swing, +/- relative (from the Delta sgn(x') term).
    condition_number : numpy.ndarray
        Of the scaled normal equations of the fit over every used row (all columns).
    settled : numpy.ndarray
        No drift (:func:`drift_free`): af and a1 over the first half of the periods and over the second half
        agree within the settle band or, from :data:`DRIFT_MIN_PERIODS` periods on, within the periods' noise.
    samples : numpy.ndarray
        Rows the estimate used (the core rows).
    columns : tuple of str
        Names of the coefficients.
    systematic_rms_v : numpy.ndarray
        The residual's part that repeats from period to period (RMS, V): the model's misfit.
    spread_se : numpy.ndarray
        ([N,] p) standard error of the mean from the periods' spread, with the held gain terms' error added (the
        same in every period, the spread does not see it; NaN with fewer than two periods).
    ls_std : numpy.ndarray
        ([N,] p) the least-squares standard error, from the residual, with the held gain terms' error added.
    periods_used : numpy.ndarray
        Periods with rows enough for their own solution (the spread's degrees of freedom are one fewer).
    core_shift : numpy.ndarray
        ([N,] p) the fit over every used row minus the estimate (the core rows' fit, :func:`core_rows`): where the
        model holds, both estimate the same values and this is noise; where it misses what happens at reversals
        (stick windows, Stribeck friction), the rows near them pull the fit over every row, and this is how far.
    term_rms_v : numpy.ndarray
        ([N,] p) each coefficient's term in the drive (the coefficient times its regressor), RMS over the estimate's
        rows: a misfit of this size, were it all in the term, would move the coefficient by all of it.
    """

    theta: np.ndarray
    block_theta: np.ndarray
    std: np.ndarray
    blocks: int
    residual_rms_v: np.ndarray
    spread_rel: dict[str, np.ndarray]
    gain_variation_rel: np.ndarray
    condition_number: np.ndarray
    settled: np.ndarray
    samples: np.ndarray = field(default_factory=lambda: np.zeros(0))
    columns: tuple[str, ...] = ()
    systematic_rms_v: np.ndarray = field(default_factory=lambda: np.zeros(0))
    spread_se: np.ndarray = field(default_factory=lambda: np.zeros(0))
    ls_std: np.ndarray = field(default_factory=lambda: np.zeros(0))
    periods_used: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))
    core_shift: np.ndarray = field(default_factory=lambda: np.zeros(0))
    term_rms_v: np.ndarray = field(default_factory=lambda: np.zeros(0))

    def value(self, name: str) -> np.ndarray:
        """The estimate of one coefficient (``af``, ``a1``, ``d2``...)."""
        return self.theta[..., self.columns.index(name)]

    def std_of(self, name: str) -> np.ndarray:
        """Its standard error."""
        return self.std[..., self.columns.index(name)]

    def relative_figures(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        """A coefficient's standard error and its core shift, both relative to its estimate."""
        value = self.value(name)
        with np.errstate(divide="ignore", invalid="ignore"):
            return (np.abs(self.std_of(name) / value),
                    self.core_shift[..., self.columns.index(name)] / value)


@dataclass
class _Normal:
    """One least-squares solution of summed normal equations, scaled (``theta_n``), and what comes with it."""

    theta_n: np.ndarray  # (N, p)
    ssr: np.ndarray  # (N,) sum of squared residuals
    rows: np.ndarray  # (N,)
    cov_diag: np.ndarray  # (N, p) the least-squares variances, scaled
    block_n: np.ndarray | None = None  # (blocks, N, p): each period on its own (NaN: too few rows)
    condition_number: np.ndarray | None = None  # (N,) of the scaled normal equations
    gain_cov: np.ndarray | None = None  # (N, g, g) the gain terms' covariance (the fit whose gain terms are held)
    held_var: np.ndarray | None = None  # (N, p) the variance the held gain terms' error adds, the same every period


def _normal(A: np.ndarray, z: np.ndarray, yy: np.ndarray, count: np.ndarray, scale: np.ndarray,
            held: _Normal | None = None) -> _Normal:
    """Solve the normal equations summed over blocks (``A`` (blocks, N, p, p)...).

    ``scale``: the columns' scale (N, p), the same for every sub-fit so that their solutions compare. Without
    ``held`` (the fit over every row) it gives the condition number, the model-fit figures' fit needs, and the
    gain terms' covariance; with ``held``, a solution whose gain terms (the last ``len(GAIN_TERMS)`` columns) this
    one keeps, solving for the others, it gives each block's own solution, the estimate's spread needs (each only
    where it is used: the early stop solves at every period's end), and its covariance with the held terms' error
    in it (:func:`_held_covariance`)."""
    p = A.shape[-1]
    q = p - len(GAIN_TERMS) if held is not None else p
    A_full, z_full = A.sum(axis=0), z.sum(axis=0)
    z_q, A_q = z[..., :q], A[..., :q, :q]
    if held is not None:  # the held terms' share taken off the target: z_q - A_qg theta_g
        z_q = z_q - np.einsum("bnqg,ng->bnq", A[..., :q, q:], held.theta_n[:, q:])
    # a ridge on the scaled diagonal: a test with no rows (no core rows, say) gets 0, not a singular matrix
    ridge = 1e-12 * np.eye(q) * scale[:, :q, None] * scale[:, None, :q]
    A_sum = A_q.sum(axis=0)
    theta_n = np.linalg.solve(A_sum + ridge, z_q.sum(axis=0)[..., None])[..., 0]
    inverse = np.linalg.inv(A_sum + ridge)
    block_n = cond = None
    if held is None:
        cond = np.linalg.cond(A_sum / scale[:, :q, None] / scale[:, None, :q])
    else:
        enough = count >= 4 * p
        safe_A = np.where(enough[..., None, None], A_q, np.eye(q))
        block_n = np.linalg.solve(safe_A + 1e-12 * np.eye(q),
                                  np.where(enough[..., None], z_q, 0.0)[..., None])[..., 0]
        block_n = np.where(enough[..., None], block_n, np.nan)
        theta_n = np.concatenate((theta_n, held.theta_n[:, q:]), axis=-1)
        block_n = np.concatenate((block_n, np.broadcast_to(held.theta_n[:, q:], block_n.shape[:-1] + (p - q,))),
                                 axis=-1)
    rows = count.sum(axis=0)
    ssr = yy.sum(axis=0) - 2 * np.einsum("np,np->n", theta_n, z_full) + np.einsum("np,npq,nq->n", theta_n, A_full,
                                                                                     theta_n)
    ssr = np.maximum(ssr, 0.0)
    sigma2 = ssr / np.maximum(rows - q, 1)
    if held is None:
        g = len(GAIN_TERMS)
        return _Normal(theta_n, ssr, rows, np.einsum("nqq->nq", inverse) * sigma2[:, None], block_n, cond,
                       gain_cov=inverse[:, p - g:, p - g:] * sigma2[:, None, None])
    cov_diag, held_var = _held_covariance(A_full, inverse, held, sigma2)
    return _Normal(theta_n, ssr, rows, cov_diag, block_n, cond, held_var=held_var)


def _held_covariance(A_full: np.ndarray, inverse: np.ndarray, held: _Normal,
                     sigma2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The variances of a fit with the gain terms held at another fit's, whose error they carry in.

    With the gain terms g held at theta_g, the others solve A_qq theta_q = z_q - A_qg theta_g: an error in theta_g
    moves theta_q by -M (theta_g's error), M = A_qq^-1 A_qg. theta_g's error, the fit over every row's, is the same
    in every period, so the periods' spread does not see it; it adds ``held_var`` = diag(M Cov_g M') to both of
    the estimate's errors. Its covariance with the core rows' own noise (the core rows are rows of that fit too) is
    left out: it is zero where the core rows are every row, and its sign depends on the rows the core leaves out
    (docs/method.md, section 7, an open limitation).

    Returns
    -------
    (cov_diag, held_var)
        (N, p) each: the least-squares variances (the core rows' own noise plus ``held_var``; the gain terms keep
        the held fit's), and ``held_var`` (0 for the gain terms themselves).
    """
    q = inverse.shape[-1]
    M = inverse @ A_full[:, :q, q:]  # (N, q, g)
    extra = np.maximum(np.einsum("nqg,ngh,nqh->nq", M, held.gain_cov, M), 0.0)
    own = np.einsum("nqq->nq", inverse) * sigma2[:, None]
    held_gain = held.cov_diag[:, q:]
    return (np.concatenate((own + extra, held_gain), axis=-1),
            np.concatenate((extra, np.zeros_like(held_gain)), axis=-1))


def solve(acc: BlockAccumulator, blocks: int, settle_band_rel: float) -> PeriodFit | None:
    """The fit over the first ``blocks`` blocks (None if there are none); vectorised over tests.

    The estimate is the fit over the core rows (:func:`core_rows`: clear of any stick, whose forces the sgn(x')
    model cannot explain); the model-fit figures (the residual and its repeating part) are the fit's over every
    used row, where a misfit shows (:attr:`PeriodFit.core_shift` is the distance between the two)."""
    if blocks <= 0:
        return None
    with np.errstate(invalid="ignore", divide="ignore"):  # a test left without rows has NaN figures, said as such
        return _solve(acc, blocks, settle_band_rel)


def _solve(acc: BlockAccumulator, blocks: int, settle_band_rel: float) -> PeriodFit:
    setup = acc.setup
    scale = np.sqrt(np.maximum(np.einsum("npp->np", acc.A[:blocks].sum(axis=0)), 1e-300))
    every = _normal(acc.A[:blocks], acc.z[:blocks], acc.yy[:blocks], acc.count[:blocks], scale)
    # the core rows see less of the swing's ends, where the gain terms show: they keep the fit over every row's
    core = _normal(acc.A_core[:blocks], acc.z_core[:blocks], acc.yy_core[:blocks], acc.count_core[:blocks], scale,
                   held=every)
    residual_rms = np.sqrt(every.ssr / np.maximum(every.rows, 1))
    systematic_rms = _systematic_rms(acc, blocks, every.theta_n)
    units = np.array([setup.scales[i] for i in setup.estimated] + list(setup.scales[6:]))
    theta = core.theta_n / units
    block_theta = core.block_n / units
    ls_std = np.sqrt(np.maximum(core.cov_diag, 0.0)) / units
    good = np.isfinite(block_theta).all(axis=-1)
    used = good.sum(axis=0)
    spread_sd = np.sqrt(np.nansum(np.where(good[..., None], (block_theta - theta) ** 2, 0.0), axis=0)
                        / np.maximum(used - 1, 1)[:, None])
    spread_sd = np.where((used >= 2)[:, None], spread_sd, np.nan)  # one period: no spread known
    # the held gain terms' error is the same in every period: the spread cannot see it, so it is added (it is in
    # ls_std already)
    spread_se = np.sqrt(spread_sd ** 2 / np.maximum(used, 1)[:, None] + core.held_var / units ** 2)
    std = np.maximum(spread_se, ls_std)
    core_shift = (every.theta_n - core.theta_n) / units
    cols = setup.columns
    i_af, i_a1, i_df = cols.index("af"), cols.index("a1"), cols.index("df")
    af, a1 = theta[:, i_af], theta[:, i_a1]
    spread = {"af": spread_sd[:, i_af] / np.abs(af), "a1": spread_sd[:, i_a1] / np.abs(a1)}
    # a model-fit figure, as the residual's: the fit over every row's (the core rows see less of the swing's ends)
    every_theta = every.theta_n / units
    gain_variation = np.abs(every_theta[:, i_df] / every_theta[:, i_af]) * setup.swing_mm
    # settled: every period has its own estimate, and af's and a1's show no drift (noise, a CAN adapter's jitter
    # mostly, scatters a1 4 % per period through usb-fs on p-edc-hard: two half means 2.3 % apart on a pump that
    # fits and does not drift)
    settled = used == blocks
    for i in (i_af, i_a1):
        settled = settled & drift_free(block_theta[:, :, i], theta[:, i], settle_band_rel)
    return PeriodFit(theta, block_theta, std, blocks, residual_rms, spread, gain_variation, every.condition_number,
                     settled, core.rows, cols, systematic_rms, spread_se, ls_std, used, core_shift,
                     _term_rms(acc.A_core[:blocks], core))


def _term_rms(A: np.ndarray, fit: _Normal) -> np.ndarray:
    """(N, p) RMS of each coefficient's term in the drive over ``fit``'s rows (``A``: their normal equations)."""
    mean_square = np.einsum("bnpp->np", A) / np.maximum(fit.rows, 1)[:, None]
    return np.abs(fit.theta_n) * np.sqrt(mean_square)


def _systematic_rms(acc: BlockAccumulator, blocks: int, theta_n: np.ndarray) -> np.ndarray:
    """The residual's part that repeats from one period to the next, for the scaled solution ``theta_n``.

    r_b . r_b' over the pairs of rows at the same phase of two periods: noise, not the same twice, averages out
    of it (it can come out below 0 by noise: none)."""
    pair_ss = (acc.pair_yy[1:blocks].sum(axis=0) - np.einsum("np,np->n", theta_n, acc.pair_xy[1:blocks].sum(axis=0))
               + np.einsum("np,npq,nq->n", theta_n, acc.pair_xx[1:blocks].sum(axis=0), theta_n))
    pairs = acc.pair_count[1:blocks].sum(axis=0)
    return np.where(pairs > 0, np.sqrt(np.maximum(pair_ss, 0.0) / np.maximum(pairs, 1)), np.nan)


def reference_condition_number(design: ControllerDesign) -> float:
    """Condition number of the reference's regressors over the steady excitation where it slides, for the variant's
    whole duration: identifiability is the excitation's (the trust rule judges the worse of this and the fit's,
    :func:`edc_bench.identification.trust.judged_condition_number`)."""
    from edc_bench.control.fel import condition_number, regressor_matrix

    T = design.period_s
    t = np.arange(int(round((design.move_s + design.fade_s) / T)), design.ticks) * T
    phi = regressor_matrix(design.reference(design.mid_mm), t, T)
    keep = np.abs(phi[:, 2]) >= design.reversal_speed_mm_s
    return condition_number(phi[keep][:, list(design.estimated)])


def trace_rows(setup: FitSetup, trace: dict[str, np.ndarray], reference_resistance_ohm: float,
               span: slice = slice(None)) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """:func:`rows` of a loop's trace columns over ``span`` (a tick's sample counts if its reply came in time and
    the tick was not lost in a gap): for the finished trace, and for the early stop's steps as the test runs."""
    rho = np.asarray(trace["coil_resistance_ohm"][span], dtype=float) / reference_resistance_ohm
    valid = trace["reply_ok"][span].astype(bool) & ~trace["gap"][span].astype(bool)
    return rows(setup, trace["position_mm"][span], trace["drive_v"][span], rho,
                trace["reference_velocity_mm_s"][span], valid)


def trace_blocks(setup: FitSetup, trace: dict[str, np.ndarray],
                 reference_resistance_ohm: float = 1.0) -> tuple[BlockAccumulator, int]:
    """The normal equations of a loop's trace per block, and how many blocks are complete.

    Parameters
    ----------
    setup : FitSetup
    trace : dict of numpy.ndarray
        The filled trace columns (``position_mm``, ``drive_v``, ``coil_resistance_ohm``,
        ``reference_velocity_mm_s``, ``reply_ok``, ``gap``).
    reference_resistance_ohm : float
        The reference coil's resistance (rho = measured / reference).
    """
    ticks = len(trace["t_s"])
    blocks = setup.blocks_in(ticks)
    acc = BlockAccumulator(setup, max(blocks, 1))
    if blocks == 0:
        return acc, 0
    accumulate(setup, acc, 0, *trace_rows(setup, trace, reference_resistance_ohm))
    return acc, blocks


def expected_drive_noise_v(variant: Variant) -> float:
    """The noise the position sensor alone leaves in the smoothed drive (V rms): the residual's yardstick.

    White sensor noise sigma (noise and quantisation) through ``kp e + D(e)``, D the PID's filtered difference
    ``d_k = a d_{k-1} + b (e_k - e_{k-1})``, then through the fit's smoothing: sigma^2 times the sum of the squared
    impulse response. The integrator's share is negligible at the tick rate.
    """
    from edc_bench.control.law import derivative_filter_coefficients
    from edc_bench.control.pid import PidGains

    c = variant.controller
    lvdt = variant.sensors.lvdt
    sigma2 = lvdt.noise_sd ** 2 + lvdt.resolution ** 2 / 12.0
    gains = PidGains(c.kp_v_per_mm, c.ki_v_per_mm_s, c.kd_v_s_per_mm, c.derivative_filter_hz)
    a, b = derivative_filter_coefficients(gains, c.period_s)
    # impulse response of kp e + D(e) (D: d_k = a d_{k-1} + b (e_k - e_{k-1})), then the smoothing the fit applies
    setup = FitSetup.from_variant(variant)
    n = 20 * setup.window
    impulse = np.zeros(n)
    impulse[0] = c.kp_v_per_mm + b
    impulse[1:] = b * (a - 1.0) * a ** np.arange(n - 1)
    smoothed = np.convolve(impulse, _smoothing_kernels(setup.window, setup.period_s)[0][::-1])
    return math.sqrt(sigma2 * float(smoothed @ smoothed))
