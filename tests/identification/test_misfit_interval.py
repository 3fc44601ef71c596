"""The misfit's share of a verdict's interval (issue #37 items 1-3): the core rows, the core shift, the interval's
three parts, and the simulated plant whose position-dependent pull no longer lags.

A row of the period fit is a weighted sum over its smoothing window; a window that reaches into a stick or a
breakaway smooths forces the sgn(x') model cannot explain into the row. The core rows are those whose window slides
throughout; the estimate is the fit over them, and the fit over every used row moves away from it exactly when that
happens (the core shift); the interval carries twice that distance beyond the baseline's.
"""

from __future__ import annotations

import numpy as np
import pytest

from edc_bench.bench import run_simulated_test
from edc_bench.config import load_variant, parse_variant, with_changes
from edc_bench.experiments.coverage import A1, AF, stick_slip_variant
from edc_bench.identification.period_fit import (
    MISFIT_ALLOWANCE,
    RESIDUAL_ALLOWANCE,
    SPEED_SPAN_TICKS,
    FitSetup,
    core_rows,
)
from edc_bench.physics.valve import ValveSpec
from edc_bench.population.batch import run_batch
from edc_bench.verdict.baseline import BaselineTest, baseline_from_tests
from edc_bench.verdict.early_stop import Interval, relative_box


@pytest.fixture(scope="module")
def setup() -> FitSetup:
    return FitSetup.from_variant(load_variant("p-edc-default"))


def _windows(setup: FitSetup, ticks: int) -> tuple[np.ndarray, np.ndarray]:
    half = setup.window // 2
    k = np.arange(ticks)
    return np.maximum(k - half, 0), np.minimum(k + half + 2, ticks)


def test_a_row_is_core_only_if_its_whole_window_slides(setup) -> None:
    """A rack that sweeps at 10 mm/s, stands still for 30 ms, and sweeps on: every row whose window reaches the
    stand-still is out, every other row in."""
    T, ticks = setup.period_s, 600
    speed = np.full(ticks, 10.0)
    speed[300:330] = 0.0
    x = np.concatenate(([0.0], np.cumsum(speed[:-1] * T)))
    lo, hi = _windows(setup, ticks)
    core = core_rows(setup, x, lo, hi)
    half, m = setup.window // 2, SPEED_SPAN_TICKS
    assert setup.exclusion_mm_s < 10.0
    # a sample is slow when its 11-sample straight line is slower than the exclusion's speed, and a row is out
    # when the part of its window those lines fit in (half a window less m either side) reaches a slow sample
    out = np.flatnonzero(~core[m + half: ticks - m - half - 1]) + m + half
    print(f"rows out: {out.min()}..{out.max()} of a stand-still over samples 300..329")
    assert len(out) == out.max() - out.min() + 1  # one stretch, around the stand-still
    assert abs(out.min() - (300 - (half - m))) <= 3 and abs(out.max() - (330 + (half - m))) <= 3


def test_core_rows_are_the_same_however_the_trace_is_cut(setup) -> None:
    """The early stop feeds rows a step at a time: a row's flag depends on its own window only."""
    rng = np.random.default_rng(4)
    T, ticks = setup.period_s, 2000
    t = np.arange(ticks) * T
    x = 4.0 * np.sin(2 * np.pi * 0.5 * t) + 0.5 * np.sin(2 * np.pi * 3.0 * t) + rng.normal(0, 0.003, ticks)
    whole = core_rows(setup, x, *_windows(setup, ticks))
    half = setup.window // 2
    for start, stop in ((0, 700), (650, 1400), (1300, 2000)):
        part = core_rows(setup, x[start:stop], *_windows(setup, stop - start))
        inner = slice(half, stop - start - half - 1)  # a span's edge rows are never used
        np.testing.assert_array_equal(part[inner], whole[start:stop][inner])
    assert 0.2 < (~whole).mean() < 0.8  # reversals leave a good share of rows out


@pytest.mark.slow  # 15 s: the default suite stays under 5 minutes; CI's slow pass runs it
def test_the_core_shift_is_small_where_the_model_holds_and_large_where_friction_leaks_into_it() -> None:
    default = load_variant("p-edc-default")
    sticky = stick_slip_variant(default)
    new = default.valve.clearance_new_mm
    plain = run_batch(default, [ValveSpec(new)], [0], stiction=False)
    stuck = run_batch(sticky, [ValveSpec(new, friction_scale=3.0)], [0])
    shifts = {}
    for name, result in (("plain", plain), ("sticky", stuck)):
        fit = result.periods.at(result.periods.blocks).fit
        shifts[name] = {f: float(fit.relative_figures(f)[1][0]) for f in ("af", "a1")}
        shifts[name]["a1_error"] = float(result.parameters[0, A1] / result.truth[0, A1] - 1.0)
        shifts[name]["af_error"] = float(result.parameters[0, AF] / result.truth[0, AF] - 1.0)
    print(shifts)
    assert abs(shifts["plain"]["a1"]) < 0.005 and abs(shifts["plain"]["af"]) < 0.005
    # friction at reversals pulls the fit over every row: it reads a1 more than 3 % lower than the estimate (the
    # core rows' fit), which is within 2.5 % of the truth (it was -7.2 % when the estimate was the fit over every row)
    assert shifts["sticky"]["a1"] < -0.03
    assert abs(shifts["sticky"]["a1_error"]) < 0.025
    # the estimate keeps less than half of the shift, which the interval's misfit part allows twice over
    assert abs(shifts["sticky"]["a1_error"]) < 0.5 * abs(shifts["sticky"]["a1"]) and MISFIT_ALLOWANCE >= 2


@pytest.mark.slow  # seconds: CI's slow pass runs it (the default suite stays under 5 minutes on CI)
def test_the_interval_is_the_noise_plus_twice_the_shift_beyond_the_baseline_s_plus_the_baseline_s_noise() -> None:
    """The misfit moves a ratio by the difference between the valve's share and the baseline's: twice the
    difference of their core shifts, and the repeating residual beyond the baseline's; the baseline's tests' noise
    moves every ratio."""
    variant = stick_slip_variant(load_variant("p-edc-default"))
    variant = with_changes(variant, {"excitation": {"duration_s": 15.0}}, "a shorter test")  # 5 periods: all it needs
    result = run_batch(variant, [ValveSpec(variant.valve.clearance_new_mm, friction_scale=2.0)], [0])
    at = result.periods.at(5)
    base = at.parameters[0, [AF, A1]] * np.array([0.8, 1.25])  # ratios 1.25 and 0.8
    interval = Interval.of(variant, result.periods.blocks)
    systematic_v = float(at.fit.systematic_rms_v[0])
    tests = [BaselineTest(0.07, 0.004, af_se_rel=0.003, a1_se_rel=0.004, af_core_shift_rel=0.002,
                          a1_core_shift_rel=-0.004, systematic_rms_v=0.5 * systematic_v),
             BaselineTest(0.07, 0.004, af_se_rel=0.004, a1_se_rel=0.003, af_core_shift_rel=0.004,
                          a1_core_shift_rel=-0.002, systematic_rms_v=0.7 * systematic_v)]
    baseline = baseline_from_tests(tests)
    box = relative_box(at.parameters[:, [AF, A1]], at.fit, base, interval, baseline)
    bare = relative_box(at.parameters[:, [AF, A1]], at.fit, base, interval)
    np.testing.assert_allclose(box.centre, [[1.25, 0.8]], rtol=1e-12)
    np.testing.assert_array_equal(box.statistical, bare.statistical)
    shift = np.array([at.fit.relative_figures(f)[1][0] for f in ("af", "a1")])
    assert shift[1] < -0.01  # the friction pulls this valve's a1 well beyond the baseline's -0.3 %
    np.testing.assert_allclose(box.misfit[0], MISFIT_ALLOWANCE * np.abs(shift - [0.003, -0.003]) * [1.25, 0.8],
                               rtol=1e-12)
    np.testing.assert_allclose(bare.misfit[0], MISFIT_ALLOWANCE * np.abs(shift) * [1.25, 0.8], rtol=1e-12)
    np.testing.assert_allclose(box.baseline[0], interval.z * 0.005 / 2 * np.array([1.25, 0.8]), rtol=1e-12)
    assert not bare.baseline.any()
    # the repeating residual beyond the baseline's tests' mean (0.6 of this test's), in quadrature, over each term
    assert systematic_v > 0
    term = at.fit.term_rms_v[0, [at.fit.columns.index("af"), at.fit.columns.index("a1")]]
    np.testing.assert_allclose(box.residual[0], RESIDUAL_ALLOWANCE * 0.8 * systematic_v / term * [1.25, 0.8],
                               rtol=1e-12)
    np.testing.assert_allclose(bare.residual[0], RESIDUAL_ALLOWANCE * systematic_v / term * [1.25, 0.8], rtol=1e-12)
    np.testing.assert_allclose(box.half_width, box.statistical + box.misfit + box.baseline + box.residual,
                               rtol=1e-15)
    np.testing.assert_array_equal(box.fixed, box.misfit + box.baseline + box.residual)


def _no_stribeck(name: str):
    data = load_variant(name).model_dump()
    data["valve"]["stiction_ratio"] = 1.0  # breakaway = Coulomb: the Stribeck term has nothing to fall from
    return parse_variant(data)


@pytest.mark.slow  # 9 s, as above
def test_the_plant_s_position_dependent_pull_does_not_lag_into_damping() -> None:
    """On the hard pump (force constant +/-10 % over the swing) a new valve's a1 read +2.1 % when the plant held
    the pull's position-dependent part at each step's start: a force lagging the rack by half a step acts as
    damping (k_i s i_0 T/2, 2 % of a new valve's). Taken at mid-step, both plants (the simulated rig's and the batch
    path's) give the truth within noise."""
    variant = _no_stribeck("p-edc-hard")
    assert variant.coil.force_constant_variation_per_mm > 0
    batch = run_batch(variant, [ValveSpec(variant.valve.clearance_new_mm)], [0])
    batch_error = batch.parameters[0] / batch.truth[0] - 1.0
    rig = run_simulated_test(variant, "new", 0, nominal_baseline=True, full_length=True)
    rig_error = {name: entry.error_rel for name, entry in rig.parameters.items()}
    print(f"a1 batch {batch_error[A1]:+.2%}, simulated rig {rig_error['a1']:+.2%}")
    assert abs(batch_error[A1]) < 0.008 and abs(rig_error["a1"]) < 0.008
    assert abs(batch_error[AF]) < 0.008 and abs(rig_error["af"]) < 0.008


def test_a_test_without_a_single_core_row_is_never_settled_and_does_not_crash(setup) -> None:
    """A valve that chatters in every smoothing window has used rows but no core rows: the estimate (the core rows'
    fit) is then all ridge, no period has its own estimate, and the test is not settled, so never trusted (a review
    found that a rank-one ridge made this a singular matrix)."""
    from edc_bench.identification.period_fit import BlockAccumulator, accumulate, solve

    rng = np.random.default_rng(1)
    p = len(setup.columns)
    for draw in range(4):
        ticks = 3 * setup.block_ticks
        X = rng.normal(size=(ticks, p))
        y = X @ rng.normal(size=p) + 1e-3 * rng.normal(size=ticks)
        use = np.ones(ticks, dtype=bool)
        acc = BlockAccumulator(setup, 3)
        accumulate(setup, acc, setup.first_tick, X, y, use, np.zeros(ticks, dtype=bool))
        fit = solve(acc, 3, 0.02)
        assert not fit.settled.any() and fit.periods_used[0] == 0 and fit.samples[0] == 0, draw
        assert np.all(np.isfinite(fit.theta)) and np.all(np.isfinite(fit.core_shift)), draw


@pytest.mark.slow  # 10 s, as above
def test_a_misfit_away_from_the_reversals_widens_the_interval_until_it_holds_the_truth() -> None:
    """#37 item 3: a solenoid whose gain varies +20 % over the swing, beyond the model's series. The fit still
    passes the model-fit rule, its repeating residual a few times the noise; the misfit is spread over the swing, so
    the core shift hardly moves, and its a1 ratio is more than 5 points off the truth. Without its residual part
    the box would not hold the truth."""
    from edc_bench.experiments.studies import with_gain_variation
    from edc_bench.identification.analysis import model_fits
    from edc_bench.identification.period_fit import expected_drive_noise_v
    from edc_bench.population.valves import draw_population
    from edc_bench.verdict.baseline import load_baseline

    hard = load_variant("p-edc-hard")
    variant = with_gain_variation(hard, 0.20)
    valve = draw_population(hard, 40, 7)[13]
    result = run_batch(variant, [valve], [700_013])
    at = result.periods.at(6)
    baseline = load_baseline(hard, station=False)
    base = np.array([baseline.af_v, baseline.a1_v_s_per_mm])
    box = relative_box(at.parameters[:, [AF, A1]], at.fit, base, Interval.of(variant, result.periods.blocks),
                       baseline)
    noise_v = expected_drive_noise_v(variant)
    ratio = float(at.fit.systematic_rms_v[0]) / noise_v
    error = np.abs(box.centre[0] - result.truth[0, [AF, A1]] / base)
    print(f"repeating residual {ratio:.2f}x noise; |ratio - truth| {error}; half width {box.half_width[0]}, "
          f"of which residual {box.residual[0]}, misfit at reversals {box.misfit[0]}")
    assert model_fits(variant, at.fit, noise_v)[0] and 2.0 < ratio < hard.acceptance.max_residual_ratio
    assert error[1] > 0.05 and np.any(error > (box.half_width - box.residual)[0])  # without it: not held
    assert np.all(error <= box.half_width[0])
