"""The period fit's misfit measure: the residual's part that repeats from one excitation period to the next.

Synthetic rows, so that the truth is known: a target that is the model plus a misfit repeating every period plus
white noise. The noise must drop out of the repeating part, the misfit must not.
"""

from __future__ import annotations

import numpy as np
import pytest

from edc_bench.config import load_variant
from edc_bench.identification.period_fit import (
    DRIFT_CRITICAL,
    BlockAccumulator,
    FitSetup,
    accumulate,
    drift_free,
    solve,
)

BLOCKS = 6


@pytest.fixture(scope="module")
def setup() -> FitSetup:
    return FitSetup.from_variant(load_variant("p-edc-default"))


def _rows(setup: FitSetup, misfit_v: float, noise_v: float, seed: int = 0):
    rng = np.random.default_rng(seed)
    ticks = BLOCKS * setup.block_ticks
    p = len(setup.columns)
    X = rng.normal(size=(ticks, p))
    theta = rng.normal(size=p)
    phase = np.arange(ticks) % setup.block_ticks
    # the same shape every period (three harmonics of it), rms misfit_v
    shape = sum(np.sin(2 * np.pi * h * phase / setup.block_ticks + h) for h in (1, 2, 5)) / np.sqrt(1.5)
    y = X @ theta + misfit_v * shape + noise_v * rng.normal(size=ticks)
    use = rng.random(ticks) > 0.3  # rows left out (stick windows, missing replies)
    return X, np.where(use, y, 0.0), use


def _fit(setup: FitSetup, X, y, use, span: int | None = None):
    acc = BlockAccumulator(setup, BLOCKS)
    start = setup.first_tick
    if span is None:
        accumulate(setup, acc, start, X, y, use)
        return acc
    # as the batch path and the stop rule feed it: spans overlapping by the smoothing's half window, their edge rows
    # not used, so that a span's first rows can belong to the period before the one its predecessor ended in
    edge = 20
    for lo in range(0, len(X), span):
        a, b = max(lo - edge, 0), min(lo + span + edge, len(X))
        mine = np.zeros(b - a, dtype=bool)
        mine[lo - a: min(lo + span, len(X)) - a] = True
        accumulate(setup, acc, start + a, X[a:b], y[a:b], use[a:b] & mine)
    return acc


def test_noise_drops_out_of_the_repeating_part_and_a_repeating_misfit_stays(setup) -> None:
    noise = 1e-3
    for misfit in (0.0, 0.5e-3, 2e-3):
        fit = solve(_fit(setup, *_rows(setup, misfit, noise)), BLOCKS, 0.02)
        print(f"misfit {misfit * 1e3:.1f} mV, noise 1 mV: residual {fit.residual_rms_v[0] * 1e3:.3f} mV, "
              f"repeating {fit.systematic_rms_v[0] * 1e3:.3f} mV")
        assert fit.residual_rms_v[0] == pytest.approx(np.hypot(misfit, noise), rel=0.03)
        assert fit.systematic_rms_v[0] == pytest.approx(misfit, abs=0.15 * noise)


def test_more_noise_raises_the_residual_but_not_its_repeating_part(setup) -> None:
    quiet = solve(_fit(setup, *_rows(setup, 2e-3, 0.5e-3, seed=1)), BLOCKS, 0.02)
    noisy = solve(_fit(setup, *_rows(setup, 2e-3, 5e-3, seed=1)), BLOCKS, 0.02)
    assert noisy.residual_rms_v[0] > 2.5 * quiet.residual_rms_v[0]
    assert noisy.systematic_rms_v[0] == pytest.approx(quiet.systematic_rms_v[0], rel=0.15)


def test_fed_in_overlapping_spans_it_is_what_one_pass_gives(setup) -> None:
    rows = _rows(setup, 1e-3, 1e-3, seed=2)
    whole, spans = _fit(setup, *rows), _fit(setup, *rows, span=500)
    for name in ("A", "z", "yy", "count", "pair_yy", "pair_xy", "pair_xx", "pair_count"):
        np.testing.assert_allclose(getattr(spans, name), getattr(whole, name), rtol=1e-9, atol=1e-12, err_msg=name)


def test_one_period_has_no_repeating_part_to_measure(setup) -> None:
    fit = solve(_fit(setup, *_rows(setup, 1e-3, 1e-3)), 1, 0.02)
    assert np.isnan(fit.systematic_rms_v[0])


def test_a_trial_feed_on_a_copy_leaves_the_sums_as_they_were(setup) -> None:
    """The stop rule adds a period's last rows for a decision to a copy of the sums: the sums themselves are left
    alone, and the copy's fit is the fit of the sums with those rows added."""
    X, y, use = _rows(setup, 1e-3, 1e-3, seed=3)
    cut = 2 * setup.block_ticks + 1500
    core = use & (np.arange(len(X)) % 7 != 0)  # some used rows are not core rows
    acc = BlockAccumulator(setup, BLOCKS)
    accumulate(setup, acc, setup.first_tick, X[:cut], y[:cut], use[:cut], core[:cut])
    before = {name: getattr(acc, name).copy() for name in (*BlockAccumulator._SUMS, "_by_phase")}
    trial = acc.copy()
    end = 3 * setup.block_ticks
    accumulate(setup, trial, setup.first_tick + cut, X[cut:end], y[cut:end], use[cut:end], core[cut:end])
    assert trial.count_core[2].sum() > before["count_core"][2].sum()  # the trial fed core rows too
    for name, value in before.items():
        np.testing.assert_array_equal(getattr(acc, name), value, err_msg=name)
    both = acc.copy()
    accumulate(setup, acc, setup.first_tick + cut, X[cut:end], y[cut:end], use[cut:end], core[cut:end])
    assert solve(trial, 3, 0.02).value("af").tolist() == solve(acc, 3, 0.02).value("af").tolist()
    acc = both
    # and the rows fed again after give what one pass gives
    accumulate(setup, acc, setup.first_tick + cut, X[cut:], y[cut:], use[cut:], core[cut:])
    whole = _fit(setup, X, y, use)
    np.testing.assert_allclose(acc.pair_yy, whole.pair_yy, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(acc.pair_count, whole.pair_count)


def test_the_estimate_is_the_core_rows_least_squares_with_the_gain_terms_of_the_fit_over_every_row(setup) -> None:
    """solve() against explicit least squares: the fit over every used row, then the core rows' fit of the other
    columns with the gain terms held at that fit's; the core shift is the distance between them."""
    from edc_bench.identification.period_fit import GAIN_TERMS

    X, y, use = _rows(setup, 0.0, 1e-2, seed=5)
    core = use & (np.random.default_rng(6).random(len(X)) > 0.4)
    acc = BlockAccumulator(setup, BLOCKS)
    accumulate(setup, acc, setup.first_tick, X, y, use, core)
    fit = solve(acc, BLOCKS, 0.02)
    units = np.array([setup.scales[i] for i in setup.estimated] + list(setup.scales[6:]))
    q = len(setup.columns) - len(GAIN_TERMS)
    every = np.linalg.lstsq(X[use], y[use], rcond=None)[0]
    held = np.linalg.lstsq(X[core, :q], y[core] - X[core, q:] @ every[q:], rcond=None)[0]
    estimate = np.concatenate((held, every[q:]))
    np.testing.assert_allclose(fit.theta[0] * units, estimate, rtol=1e-7)
    np.testing.assert_allclose(fit.core_shift[0] * units, every - estimate, rtol=1e-6, atol=1e-9)
    assert fit.samples[0] == core.sum() and np.abs(every - estimate)[:q].max() > 0  # two different fits


def test_the_interval_takes_student_s_t_for_the_spread_of_few_periods() -> None:
    from edc_bench.verdict.early_stop import Interval

    interval = Interval.of(load_variant("p-edc-default"), 14)  # verdict_confidence 0.99
    assert interval.z == pytest.approx(2.5758, abs=1e-4)
    assert interval.t[2] == pytest.approx(9.9248, abs=1e-4)  # three periods: two degrees of freedom
    assert interval.t[12] == pytest.approx(3.0545, abs=1e-4)
    # from 3 periods to 6 the half width shrinks by sqrt(1/2) and by t(5) / t(2)
    assert interval.shrink(3, np.array([6]))[0] == pytest.approx(np.sqrt(0.5) * 4.0321 / 9.9248, rel=1e-4)


def _drifting_fit(setup: FitSetup, blocks: int, drift_rel: float, scatter_rel: float, seed: int = 0):
    """The period fit of rows whose af coefficient is 1 for the first half of the periods and 1 + drift_rel after,
    with noise that scatters each period's own af estimate by about scatter_rel."""
    rng = np.random.default_rng(seed)
    ticks = blocks * setup.block_ticks
    p = len(setup.columns)
    X = rng.normal(size=(ticks, p))
    theta = np.ones((ticks, p))
    theta[ticks // 2:, setup.columns.index("af")] += drift_rel
    noise_v = scatter_rel * np.sqrt(setup.block_ticks)  # per-period estimate: noise / sqrt(rows in a period)
    y = np.einsum("tp,tp->t", X, theta) + noise_v * rng.normal(size=ticks)
    acc = BlockAccumulator(setup, blocks)
    accumulate(setup, acc, setup.first_tick, X, y, np.ones(ticks, dtype=bool))
    return solve(acc, blocks, 0.02)


def test_noisy_estimates_that_do_not_drift_are_settled(setup) -> None:
    """Through a USB adapter a1 scatters about 4 % from period to period on p-edc-hard; the halves' means then
    differ by more than the 2 % settle band now and then (one of 200 valves in tests/population/test_latency.py,
    30 s), on a pump whose estimate does not drift. From 8 periods the drift test allows for that noise: of 40
    tests scattering 5 % a period over 10 periods, the band alone settles 9, the rule 38 (it calls noise drifting
    once in a hundred per coefficient, and af and a1 must both be settled)."""
    fits = [_drifting_fit(setup, 10, 0.0, 0.05, seed) for seed in range(40)]
    assert all(fit.spread_rel["af"][0] > 0.01 for fit in fits)
    columns = [fits[0].columns.index(name) for name in ("af", "a1")]
    band_alone = sum(all(abs(fit.block_theta[5:, 0, i].mean() - fit.block_theta[:5, 0, i].mean())
                         <= 0.02 * abs(fit.theta[0, i]) for i in columns) for fit in fits)
    settled = sum(bool(fit.settled[0]) for fit in fits)
    print(f"settled of 40: band alone {band_alone}, the rule {settled}")
    assert band_alone <= 15
    assert settled >= 37


@pytest.mark.parametrize("drift_rel", [0.03, -0.05])
def test_a_drift_beyond_the_band_and_the_noise_is_not_settled(setup, drift_rel: float) -> None:
    assert not _drifting_fit(setup, 10, drift_rel, 0.002).settled[0]


def test_a_drift_within_the_band_is_settled(setup) -> None:
    assert _drifting_fit(setup, 10, 0.01, 0.002).settled[0]


def _drift_shapes(periods: int) -> dict[str, np.ndarray]:
    k = np.arange(periods)
    return {"step at the middle": (k >= periods // 2) * 1.0, "step at a third": (k >= periods // 3) * 1.0,
            "step at a quarter": (k >= periods // 4) * 1.0, "linear": k / (periods - 1),
            "transient halving each period": 1.0 - 0.5 ** k}


@pytest.mark.parametrize("periods", [8, 14, 40])
@pytest.mark.parametrize("drift_rel", [0.10, 0.5, -2.0])
def test_a_drift_of_any_shape_and_size_beyond_the_band_is_caught(periods: int, drift_rel: float) -> None:
    """Found by review: with the noise taken from the scatter about each half's mean, a steady drift of any size
    passed (its own slope was counted as scatter), and a transient that halves each period too. Now every drift
    that moves the halves' means apart by more than twice the band is caught, whatever its shape and size (a
    transient is over within the first few periods, and moves them less the more periods there are)."""
    checked = 0
    for name, shape in _drift_shapes(periods).items():
        per_period = 1.0 + drift_rel * shape[:, None] + 0.002 * np.random.default_rng(periods).normal(size=(periods, 1))
        half = periods // 2
        if abs(per_period[half:].mean() - per_period[:half].mean()) > 2 * 0.02 * abs(per_period.mean()):
            assert not drift_free(per_period, per_period.mean(axis=0), 0.02)[0], name
            checked += 1
    assert checked >= 4  # the steps and the linear drift always; the transient where it lasts long enough


@pytest.mark.parametrize("periods", [8, 14, 30])
@pytest.mark.parametrize("scatter_rel", [0.01, 0.04, 0.10])
def test_noise_alone_is_called_drifting_at_most_once_in_a_hundred(periods: int, scatter_rel: float) -> None:
    per_period = 1.0 + scatter_rel * np.random.default_rng(periods).normal(size=(periods, 20_000))
    drifting = 1.0 - drift_free(per_period, np.ones(20_000), 0.02).mean()
    print(f"{periods} periods, scatter {scatter_rel:.0%}: called drifting {drifting:.2%}")
    assert drifting < 0.0125  # 1 % by design; 20 000 draws put the estimate within +/-0.2 points


def test_below_eight_periods_the_band_alone_decides() -> None:
    per_period = 1.0 + np.array([0.0, 0.05, -0.05, 0.0, 0.06, -0.03, 0.0])[:, None]  # halves 0 and +0.0075 apart
    assert drift_free(per_period, np.ones(1), 0.02)[0]
    per_period[4:] += 0.03
    assert not drift_free(per_period, np.ones(1), 0.02)[0]


@pytest.mark.parametrize("periods", [8, 14, 64])
def test_the_drift_table_is_the_statistic_s_99_percent_quantile_on_noise(periods: int) -> None:
    from edc_bench.experiments.studies import drift_critical_value

    table = dict(DRIFT_CRITICAL)
    assert drift_critical_value(periods, draws=100_000, seed=1) == pytest.approx(table[periods], rel=0.03)


def test_one_outlying_period_is_no_drift() -> None:
    """Found by the clean-clone CI of the successive-difference rule: one of 200 p-edc-hard valves through usb-fs
    (tests/population/test_latency.py) was 'not converged' at 30 s. Its a1 per period, relative to the estimate: the
    last period 5.8 % low where the others scatter about 1 % (the adapter's timing has heavier tails than a normal
    distribution), with a gentle trend the band allows. One outlying period is left out from 8 periods on."""
    a1 = np.array([1.012, 1.018, 1.029, 1.006, 1.008, 1.002, 1.003, 0.993, 0.995, 1.001, 1.007, 0.984, 0.942])
    halves = a1[6:].mean() - a1[:6].mean()
    assert abs(halves) > 0.02  # the band alone, over every period, called it drifting
    assert drift_free(a1[:, None], np.ones(1), 0.02)[0]
    # an outlier anywhere, on white noise
    rng = np.random.default_rng(4)
    for where in (0, 5, 12):
        per_period = 1.0 + 0.01 * rng.normal(size=(13, 1))
        per_period[where] -= 0.06
        assert drift_free(per_period, np.ones(1), 0.02)[0], where
    # but two periods are not an outlier: a step in the last two is a drift
    step = 1.0 + 0.002 * rng.normal(size=(13, 1))
    step[-2:] -= 0.2
    assert not drift_free(step, np.ones(1), 0.02)[0]


def test_the_estimate_s_errors_carry_the_held_gain_terms_error(setup) -> None:
    """The gain terms are held at the fit over every row's, whose own error is the same in every period: the
    estimate's standard errors must carry it. Monte Carlo: 600 noise draws on the same rows, whose gain columns
    correlate with the parameters' and whose core rows see less of a gain column (as of the swing's ends)."""
    import dataclasses

    from edc_bench.identification.period_fit import GAIN_TERMS

    short = dataclasses.replace(setup, block_ticks=300, first_tick=0)
    blocks, draws, noise_v = 6, 600, 0.01
    ticks, p = blocks * short.block_ticks, len(short.columns)
    q = p - len(GAIN_TERMS)
    rng = np.random.default_rng(7)
    X = rng.normal(size=(ticks, p))
    X[:, q:] += 2.0 * X[:, :len(GAIN_TERMS)]
    core = np.abs(X[:, q]) < 0.5
    y = (X @ rng.normal(size=p))[:, None] + noise_v * rng.normal(size=(ticks, draws))
    acc = BlockAccumulator(short, blocks, draws)
    every = np.ones((ticks, draws), dtype=bool)
    accumulate(short, acc, 0, np.broadcast_to(X[:, None, :], (ticks, draws, p)), y, every,
               np.broadcast_to(core[:, None], (ticks, draws)))
    fit = solve(acc, blocks, 0.02)
    units = np.array([short.scales[i] for i in short.estimated] + list(short.scales[6:]))[:q]
    scatter = fit.theta[:, :q].std(axis=0)  # the estimate's true error, over the draws
    ls_std = np.sqrt(np.mean(fit.ls_std[:, :q] ** 2, axis=0))
    spread_se = np.sqrt(np.mean(fit.spread_se[:, :q] ** 2, axis=0))
    core_only = noise_v * np.sqrt(np.diag(np.linalg.inv(X[core, :q].T @ X[core, :q]))) / units
    print("least squares / true:", ls_std / scatter, "spread / true:", spread_se / scatter,
          "core rows' own / true:", core_only / scatter)
    assert np.min(core_only / scatter) < 0.8  # the case is one where the held terms' error matters
    np.testing.assert_allclose(ls_std / scatter, 1.0, atol=0.08)
    assert np.all(spread_se / scatter > 0.92) and np.all(spread_se / scatter < 1.2)
