"""The batch path stops each test where the bench's early stop would, and finds there what it would find."""

from __future__ import annotations

import numpy as np
import pytest

from edc_bench.config import load_variant
from edc_bench.experiments.studies import early_outcome, with_gain_variation
from edc_bench.population.batch import run_batch
from edc_bench.population.batch_stop import A1, AF, BatchStopRule
from edc_bench.population.valves import draw_population
from edc_bench.sim.adapter import parse_adapter
from edc_bench.verdict.early_stop import relative_box


def _both(variant_name: str, count: int, seed: int, adapter: str | None = None, gain_variation: float = 0.0):
    variant = load_variant(variant_name)
    rule = BatchStopRule.shipped(variant)
    if gain_variation:
        variant = with_gain_variation(variant, gain_variation)
        rule = BatchStopRule.of(variant, rule.classifier, rule.baseline)
    valves = draw_population(variant, count, seed)
    seeds = [seed * 1000 + n for n in range(count)]
    link = parse_adapter(adapter) if adapter else None
    full = run_batch(variant, valves, seeds, adapter=link)
    stopped = run_batch(variant, valves, seeds, adapter=link, stop=rule)
    return variant, rule, full, stopped


@pytest.mark.parametrize(("variant_name", "adapter", "gain_variation"), [
    ("p-edc-default", None, 0.0),
    # the samples come in late: the stop waits for the period's last
    pytest.param("p-edc-default", "usb-fs", 0.0, marks=pytest.mark.slow),
    # some tests stop early because the model does not fit
    pytest.param("p-edc-hard", None, 0.25, marks=pytest.mark.slow),
])
def test_a_stopped_batch_is_the_full_batch_stopped_afterwards(variant_name: str, adapter: str | None,
                                                              gain_variation: float) -> None:
    variant, rule, full, stopped = _both(variant_name, 16, 5, adapter, gain_variation)
    periods, trusted, features, misfit = early_outcome(variant, full, rule.classifier, rule.baseline)
    out = stopped.stop
    base = np.array([rule.baseline.af_v, rule.baseline.a1_v_s_per_mm])
    assert out is not None and stopped.periods is None
    assert np.array_equal(out.periods, periods)
    assert np.array_equal(out.trusted, trusted) and np.array_equal(out.misfit, misfit)
    np.testing.assert_allclose(out.features_rel, features, rtol=1e-12)
    assert np.array_equal(out.time_s, [full.periods.stop_time_s(int(p)) for p in periods])
    # what each test had found then: the full run's period fit after the same periods
    for p in np.unique(periods):
        at, here = full.periods.at(int(p)), periods == p
        np.testing.assert_allclose(stopped.parameters[here], at.parameters[here], rtol=1e-12)
        assert np.array_equal(stopped.problems[here], at.problems[here])
        assert np.array_equal(stopped.converged[here], at.converged[here])
        np.testing.assert_allclose(out.gain_variation_rel[here], at.fit.gain_variation_rel[here], rtol=1e-9,
                                   atol=1e-12)
        # the interval it stopped with: the loop's (relative_box)
        box = relative_box(at.parameters[:, [AF, A1]], at.fit, base, rule.interval, rule.baseline)
        # the residual part's repeating residual is a difference of large sums (as the gain variation's figure),
        # whose last bits the two runs sum apart: 1e-10 of the ratio, far below any figure's resolution
        np.testing.assert_allclose(out.half_width_rel[here], box.half_width[here], rtol=1e-9, atol=1e-10)
    # a test that ended before its full length, fitting, ended certain of its verdict, and only a trusted one can
    early = (out.periods < full.periods.blocks) & ~out.misfit
    assert out.certain[early].all() and (early.any() or gain_variation)  # on the unfittable pump all end misfit
    assert out.trusted[out.certain].all() and np.isfinite(out.half_width_rel[out.trusted]).all()
    assert np.array_equal(stopped.truth, full.truth)
    # the point of stopping: most tests end well before the full length, as on the bench
    assert np.median(out.time_s) < 0.6 * variant.excitation.duration_s
    if gain_variation:
        assert out.misfit.any(), "the gain sweep's pump is meant to stop some tests as not fitting"


@pytest.mark.slow  # 10-16 s: the default suite stays under 5 minutes; CI's slow pass runs it
def test_a_batch_whose_tests_all_run_full_length_is_the_full_batch() -> None:
    """A rule that never finds a verdict certain (a band nothing leaves) ends every test at its full length with
    the full run's figures, to the bit."""
    variant = load_variant("p-edc-default")
    rule = BatchStopRule.shipped(variant)
    never = BatchStopRule(variant, _Undecided(rule.classifier), rule.baseline, rule.interval)
    valves = draw_population(variant, 6, 9)
    full = run_batch(variant, valves, list(range(6)))
    stopped = run_batch(variant, valves, list(range(6)), stop=never)
    assert np.array_equal(stopped.stop.periods, np.full(6, full.periods.blocks))
    assert np.array_equal(stopped.parameters, full.parameters)
    assert np.array_equal(stopped.problems, full.problems)
    for name in ("af", "a1"):
        assert np.array_equal(stopped.settle_s[name], full.settle_s[name], equal_nan=True)
    np.testing.assert_array_equal(stopped.coil_ohm, full.coil_ohm)


class _Undecided:
    """A classifier whose verdict changes at every corner of every box: no verdict is ever certain."""

    def __init__(self, classifier) -> None:
        self.classifier = classifier

    def verdicts(self, points: np.ndarray) -> np.ndarray:
        return np.array([str(i % 5) for i in range(len(points))], dtype=object)
