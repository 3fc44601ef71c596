"""What a test measures of the pump's other parts: the rack's friction along its stroke and the rack-travel sensor's
reading. Pure numpy on the trace (docs/diagnosis.md, "Which part is at fault").

The verdict's af and a1 are the valve's only if the rest of the fuel-injection module is sound. Three figures tell
the parts apart, each from the same trace as the period fit:

- **Friction along the stroke** (:class:`FrictionProfile`). The period fit's friction term af sgn(x') is replaced
  by K terms sgn(x') B_j(x), B_j the hat functions of K positions across the swing the rack slid through (the
  rest of the model, the solenoid's position terms Delta^2 and Delta x' included, as the period fit has it): the
  friction at each position. A worn valve's friction is the same along the stroke (its plunger slides in its
  sleeve wherever the rack is); a bent or binding rack's is not: a local rise, or a slope. The solenoid's pull
  varying over the swing divides the drive by 1 + s Delta, which tilts every term by the same -s Delta; the fit's
  Delta^2 term (-s a0 of the spring's) gives s, and the profile is put right by it, so a solenoid of that kind is
  not taken for a slope. The direction of travel is not resolved: friction that differs up and down the stroke
  differs from the spring's preload line only by a straight line (the excitation cannot tell them apart).
- **The reading at rest** (:attr:`ReadingStatistics.rest_mm`): the rack on its stop before the test moves it.
  A sensor's zero shift moves it; a bow (a sensor that is not linear) does not.
- **The reading's own statistics** (:class:`ReadingStatistics`): its noise about the smoothed trajectory against
  the sensor's stated noise, single readings that jump far out and back (spikes), and readings that fall away for
  several samples and come back (a contact that drops out). A rack cannot move 0.2 mm in a millisecond; a sensor
  or its connector can.

A sensor's gain error is measured where the baseline is (:mod:`edc_bench.verdict.part`): it scales the motion
parameters a0, a1 and a2 together (they are volts per mm of the reading), not af and b.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from edc_bench.config.models import Variant
from edc_bench.identification.period_fit import FitSetup, trace_rows

#: Positions across the swing at which the friction is fitted (hat functions between them).
PROFILE_POSITIONS = 7
#: The profile spans the positions between these quantiles of the rows that slid (the ends of the swing are crossed
#: only slowly, near the reversals the fit leaves out).
PROFILE_QUANTILES = (0.03, 0.97)
#: A reading that moves more than this in one tick is not the rack's (mm; a rack at its fastest moves a few
#: hundredths of a millimetre a tick), nor less than this many times the reading's noise.
JUMP_MM = 0.15
JUMP_NOISE_FACTOR = 15.0
#: Ticks at most at the start over which the rest reading is taken, while the reference has not moved.
REST_TICKS = 10
REST_MOVE_MM = 0.005
#: The trace's channels the reading's statistics read: the rack as sampled, whether its reply came in time, the
#: ticks lost to a host stall, the reference; and its time.
READING_CHANNELS = ("position_mm", "reply_ok", "gap", "reference_mm")
TIME_CHANNEL = "t_s"


@dataclass(frozen=True)
class FrictionProfile:
    """The rack's friction at positions across the swing, as identified (in volts, as af).

    Attributes
    ----------
    positions_mm : tuple of float
        Where the friction was fitted (mm, as the sensor reads it).
    friction_v : tuple of float
        The friction term at each position (V, with this test's coil; the solenoid's pull variation put right).
    std_v : tuple of float
        Its standard error at each position (from the spread between excitation periods, pooled over positions).
    mean_v : float
        The profile's mean (about af).
    slope_v : float
        Its straight line's rise across the profile's span (V, last position less first).
    slope_std_v : float
        The rise's standard error.
    peak_v : float
        The largest rise of one position above that straight line (V).
    peak_at_mm : float
        Where it is.
    peak_std_v : float
        Its standard error.
    gain_slope_per_mm : float
        The solenoid's pull variation the profile was put right by (per mm), from the fit's Delta^2 term.
    periods : int
        Excitation periods it rests on.
    bend_v : float
        The largest bend at one inner position of what depends on the position alike in both directions, beyond the
        spring's line and the solenoid's curve (V; 0: none): a sensor that reads unevenly there reads the spring's
        force where the rack is not.
    bend_mm : float
        That bend in millimetres read (over the fit's spring rate a0): how far the reading is off a straight line.
    bend_at_mm : float
        Where it is.
    bend_std_mm : float
        Its standard error (from the spread between excitation periods).
    """

    positions_mm: tuple[float, ...]
    friction_v: tuple[float, ...]
    std_v: tuple[float, ...]
    mean_v: float
    slope_v: float
    slope_std_v: float
    peak_v: float
    peak_at_mm: float
    peak_std_v: float
    gain_slope_per_mm: float
    periods: int
    bend_v: float = 0.0
    bend_mm: float = 0.0
    bend_at_mm: float = math.nan
    bend_std_mm: float = 0.0


@dataclass(frozen=True)
class ReadingStatistics:
    """What the rack-travel sensor's reading says of itself.

    Attributes
    ----------
    rest_mm : float
        The reading with the rack on its stop before the test moved it (median; NaN when not measured).
    noise_mm : float
        The reading's noise about the smoothed trajectory (mm, robust standard deviation), as the sensor's stated
        noise would be measured the same way.
    expected_noise_mm : float
        What the variant's stated sensor noise (noise and resolution) gives measured this way.
    spikes : int
        Single readings that jumped far out and straight back.
    dropouts : int
        Readings that fell away for several samples and came back (a contact).
    """

    rest_mm: float
    noise_mm: float
    expected_noise_mm: float
    spikes: int
    dropouts: int

    @property
    def noise_ratio(self) -> float:
        """The noise against the stated noise."""
        return self.noise_mm / self.expected_noise_mm if self.expected_noise_mm > 0 else math.inf


@dataclass(frozen=True)
class PumpSignatures:
    """What one test measured of the rack and the sensor (:func:`measure`)."""

    friction: FrictionProfile | None
    reading: ReadingStatistics


def _hat_basis(x: np.ndarray, knots: np.ndarray) -> np.ndarray:
    """(T, K) hat functions at ``knots`` (1 at its knot, falling to 0 at the next; the end ones flat beyond)."""
    x = np.clip(x, knots[0], knots[-1])
    out = np.zeros((len(x), len(knots)))
    j = np.clip(np.searchsorted(knots, x, side="right") - 1, 0, len(knots) - 2)
    w = (x - knots[j]) / (knots[j + 1] - knots[j])
    rows = np.arange(len(x))
    out[rows, j] = 1.0 - w
    out[rows, j + 1] += w
    return out


def friction_profile(variant: Variant, trace: dict[str, np.ndarray]) -> FrictionProfile | None:
    """The friction along the swing (:class:`FrictionProfile`); None where the test has too little of it (fewer
    than two whole excitation periods, or a0 and af not estimated)."""
    setup = FitSetup.from_variant(variant)
    names = setup.columns
    if "af" not in names or "a0" not in names:
        return None
    ticks = len(trace[TIME_CHANNEL])
    blocks = setup.blocks_in(ticks)
    if blocks < 2:
        return None
    X, y, use, core = trace_rows(setup, trace, variant.coil.resistance_ohm)
    scales = np.array([setup.scales[i] for i in setup.estimated] + list(setup.scales[6:]))
    raw = X * scales  # the regressors in their own units
    i_af, i_a0 = names.index("af"), names.index("a0")
    sgn, x0 = raw[:, i_af], raw[:, i_a0]
    keep_cols = [j for j, name in enumerate(names) if name not in ("af", "df", "d2f")]
    rows_ok = core.copy()
    rows_ok[: setup.first_tick] = False
    rows_ok[setup.end_tick(blocks) - setup.window // 2:] = False
    if rows_ok.sum() < 50 * PROFILE_POSITIONS:
        return None
    lo, hi = np.quantile(x0[rows_ok], PROFILE_QUANTILES)
    knots = np.linspace(lo, hi, PROFILE_POSITIONS)
    hats = _hat_basis(x0, knots)
    # first the solenoid's pull variation, from the period fit's own terms with the friction along the stroke
    A = np.concatenate([X[:, keep_cols], hats * sgn[:, None]], axis=1)
    theta = np.linalg.lstsq(A[rows_ok], y[rows_ok], rcond=None)[0]
    kept = [names[j] for j in keep_cols]
    # the solenoid's pull k_i (1 + s Delta) divides every term by 1 + s Delta: the spring's part a0 x + b becomes, to
    # the second order, C + (a0 - s C) Delta - s (a0 - s C) Delta^2 (C its value at mid-stroke), so the fit's Delta^2
    # term over its a0 is -s, whatever the friction does
    a0 = theta[kept.index("a0")] / setup.scales[3]
    d2 = theta[kept.index("d2")] / setup.scales[6]
    gain_slope = -d2 / a0 if a0 != 0 else 0.0
    correction = 1.0 + gain_slope * (knots - setup.mid_mm)
    # then the friction with the spring, the preload and whatever else depends on the position alike in both
    # directions (a sensor that is not linear reads the spring's force where the rack is not) as a force of its own
    # at each position: what differs between the directions at a position is the friction there
    # (the spring's line a0 x + b kept, with the inner positions' hats for what bends it: the end hats run flat
    # beyond the profile's span, where the spring does not)
    moving = [j for j, name in enumerate(names) if name not in ("af", "d2", "df", "d2f")]
    A = np.concatenate([X[:, moving], hats[:, 1:-1], hats * sgn[:, None]], axis=1)
    block = (np.arange(ticks) - setup.first_tick) // setup.block_ticks
    per_block = []
    for b in range(blocks):
        m = rows_ok & (block == b)
        if m.sum() < 10 * A.shape[1]:
            continue
        per_block.append(np.linalg.lstsq(A[m], y[m], rcond=None)[0])
    if len(per_block) < 2:
        return None
    theta = np.linalg.lstsq(A[rows_ok], y[rows_ok], rcond=None)[0]
    friction = theta[-PROFILE_POSITIONS:] * correction
    spread = np.array(per_block)[:, -PROFILE_POSITIONS:] * correction
    inner = slice(len(moving), len(moving) + PROFILE_POSITIONS - 2)
    bend_v, bend_mm, bend_at_mm, bend_std_mm = _bend(theta[inner], np.array(per_block)[:, inner], knots, d2, a0,
                                                     setup.mid_mm)
    periods = len(per_block)
    # the spread between periods pooled over the positions (each period's profile about its own mean level)
    deviations = spread - spread.mean(axis=0)
    pooled_sd = float(np.sqrt((deviations ** 2).sum() / max(1, (periods - 1) * PROFILE_POSITIONS)))
    std = np.full(PROFILE_POSITIONS, pooled_sd / math.sqrt(periods))
    # the highest position above a straight line through the profile; then the line through the positions away from
    # it (a bind off mid-stroke would tilt a line through all), and that position's rise above this line
    peak = int(np.argmax(friction - _line(knots, friction, np.ones(PROFILE_POSITIONS, dtype=bool))[0]))
    away = np.abs(np.arange(PROFILE_POSITIONS) - peak) > 1
    line, slope_per_mm, slope_se, line_se = _line(knots, friction, away, float(std[0]), peak)
    span = float(knots[-1] - knots[0])
    return FrictionProfile(
        positions_mm=tuple(float(k) for k in knots), friction_v=tuple(float(f) for f in friction),
        std_v=tuple(float(s) for s in std), mean_v=float(friction.mean()), slope_v=slope_per_mm * span,
        slope_std_v=slope_se * span, peak_v=float(friction[peak] - line[peak]), peak_at_mm=float(knots[peak]),
        peak_std_v=float(math.hypot(std[0], line_se)), gain_slope_per_mm=float(gain_slope), periods=periods,
        bend_v=bend_v, bend_mm=bend_mm, bend_at_mm=bend_at_mm, bend_std_mm=bend_std_mm)


def _bend(inner_v: np.ndarray, per_period_v: np.ndarray, knots: np.ndarray, d2: float, a0: float,
          mid_mm: float) -> tuple[float, float, float, float]:
    """The inner hats' largest bend beyond the solenoid's curve d2 Delta^2 (which they hold too: d2 is not among
    the profile fit's terms): in volts, in mm read, where, and its standard error in mm. The hats hold a curve as
    its values at the knots less the chord through the end knots, and the spring's force less what it would be on
    the line: -a0 times the reading's own bend."""
    curve = d2 * (knots - mid_mm) ** 2
    curve = (curve - np.interp(knots, knots[[0, -1]], curve[[0, -1]]))[1:-1]
    bends = inner_v - curve
    j = int(np.argmax(np.abs(bends)))
    sd_v = float(np.std(per_period_v[:, j], ddof=1)) / math.sqrt(len(per_period_v))
    if a0 <= 0:
        return float(abs(bends[j])), 0.0, float(knots[j + 1]), math.inf
    return float(abs(bends[j])), -float(bends[j]) / a0, float(knots[j + 1]), sd_v / a0


def _line(knots: np.ndarray, friction: np.ndarray, fit: np.ndarray, std_v: float = 0.0,
          at: int = 0) -> tuple[np.ndarray, float, float, float]:
    """The straight line through ``friction`` at the ``fit`` positions: its values at every knot, its slope (per mm),
    the slope's standard error and the line's at knot ``at`` (each position's error ``std_v``)."""
    x, y = knots[fit], friction[fit]
    centred = x - x.mean()
    slope = float(centred @ (y - y.mean()) / (centred @ centred))
    line = y.mean() + slope * (knots - x.mean())
    slope_se = std_v / math.sqrt(float(centred @ centred))
    line_se = std_v * math.sqrt(1.0 / len(x) + (knots[at] - x.mean()) ** 2 / float(centred @ centred))
    return line, slope, slope_se, line_se


def _residual_weight(setup: FitSetup) -> float:
    """How much of white noise is left in a reading less its smoothed value (the standard deviation's factor)."""
    from edc_bench.identification.period_fit import _smoothing_kernels

    w = _smoothing_kernels(setup.window, setup.period_s)[0]
    impulse = -w.copy()
    impulse[len(w) // 2] += 1.0
    return float(np.sqrt(impulse @ impulse))


def _greatest_bend_mm(variant: Variant) -> float:
    """The most the rack's step can change from one tick to the next (mm): its greatest acceleration times T^2."""
    rack, coil = variant.rack, variant.coil
    force_n = coil.force_constant_n_per_a * variant.rig.over_current_a + rack.spring_n_per_mm * rack.stroke_mm \
        + rack.preload_n
    return force_n / rack.mass_kg * 1e3 * variant.controller.period_s ** 2  # mm/s^2 times s^2


def reading_statistics(variant: Variant, trace: dict[str, np.ndarray]) -> ReadingStatistics:
    """The rest reading, the noise, the spikes and the dropouts of the rack-travel sensor's reading in ``trace``."""
    from edc_bench.identification.period_fit import _smooth, _smoothing_kernels

    setup = FitSetup.from_variant(variant)
    x, reply_ok, gap, reference = (np.asarray(trace[name], dtype=float) for name in READING_CHANNELS)
    ok = reply_ok.astype(bool) & ~gap.astype(bool) & np.isfinite(x)
    rest = math.nan
    if len(x):
        still = np.abs(reference[:REST_TICKS] - reference[0]) < REST_MOVE_MM
        at_rest = x[:REST_TICKS][still & ok[:REST_TICKS]]
        if len(at_rest) >= 5:
            rest = float(np.median(at_rest))
    lvdt = variant.sensors.lvdt
    stated_sd = math.sqrt(lvdt.noise_sd ** 2 + lvdt.resolution ** 2 / 12.0)
    factor = _residual_weight(setup)
    expected = stated_sd * factor
    if ok.sum() < 3 * setup.window:
        return ReadingStatistics(rest, math.nan, expected, 0, 0)
    filled = np.where(ok, x, np.interp(np.arange(len(x)), np.flatnonzero(ok), x[ok]))
    # the jumps first: a reading that leaves the rack's path and comes back
    step = np.diff(filled)
    noise_guess = 1.4826 * float(np.median(np.abs(step - np.median(step)))) / math.sqrt(2.0)
    jump_mm = max(JUMP_MM, JUMP_NOISE_FACTOR * noise_guess)
    # and beyond what the rack itself can do in a tick: its greatest acceleration (the solenoid at the rig's
    # over-current trip against the spring at full stroke) changes its step by no more than a T^2 (an unstable loop
    # drives the rack hard; its own motion is no spike)
    greatest_bend_mm = _greatest_bend_mm(variant)
    bend = np.abs(np.diff(filled, 2))
    bent = np.zeros(len(step), dtype=bool)
    bent[:-1] |= bend > greatest_bend_mm
    bent[1:] |= bend > greatest_bend_mm
    jumps = np.flatnonzero((np.abs(step) > jump_mm) & bent)
    spikes = dropouts = 0
    bad = np.zeros(len(x), dtype=bool)
    k = 0
    while k < len(jumps):
        start = jumps[k]
        back = [j for j in jumps[k + 1:k + 40] if np.sign(step[j]) != np.sign(step[start]) and j - start < 40]
        if not back:
            # the test ended while the reading was away (a dropout the rig tripped on): a fall far beyond what a
            # rack stopped at its end stop does in a tick
            if len(x) - start <= 40 and abs(step[start]) > 3.0 * greatest_bend_mm:
                dropouts += 1
                bad[start + 1:] = True
                break
            k += 1
            continue
        end = back[0]
        if end == start + 1:
            spikes += 1
        else:
            dropouts += 1
        bad[start + 1:end + 1] = True
        k = int(np.searchsorted(jumps, end)) + 1
    clean = np.where(bad, np.nan, filled)
    good = ~bad
    repaired = np.where(good, filled, np.interp(np.arange(len(x)), np.flatnonzero(good), filled[good]))
    kernels = _smoothing_kernels(setup.window, setup.period_s)
    smooth = _smooth(repaired[None], kernels[:1])[0]
    half = setup.window // 2
    residual = (clean - smooth)[half:len(x) - half]
    residual = residual[np.isfinite(residual)]
    noise = 1.4826 * float(np.median(np.abs(residual - np.median(residual)))) if len(residual) else math.nan
    return ReadingStatistics(rest, noise, expected, spikes, dropouts)


def measure(variant: Variant, trace: dict[str, np.ndarray]) -> PumpSignatures:
    """Every signature of one test's trace (:class:`PumpSignatures`)."""
    return PumpSignatures(friction=friction_profile(variant, trace), reading=reading_statistics(variant, trace))

