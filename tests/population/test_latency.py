"""Identification through a CAN adapter's latency: the same af, a1 and verdicts as with none (issue #12).

Measured (2026-11, 200 valves, with the period fit's second-order friction term): usb-fs af +0.18 % and a1 -0.17 %
on average, every valve within 0.6 %; no verdict changed. 5 ms round trip with 1 ms jitter: af and a1 within 0.1 %
on every valve, no verdict changed. p-edc-hard (lightly damped, a force constant varying +/-10 %) through usb-fs:
af within 0.85 %; a1 -0.72 % on average, 95 % of valves within 1.7 %, at most 2.9 % (before the term: -0.6 %, 1.5 %,
2.1 %). Through every link the model fits every valve and has converged: the repeating part of the residual is at
most 1.4x (default), 2.9x (hard), 2.0x (slow link) the sensor noise, against the limit of 5, while the whole
residual reaches 5.7x, 7.1x, 8.9x. The bounds below leave room for those figures, not more.

Each case runs the same 200 simulated used valves through the batch path twice, with the same sensor noise:
once with replies within the tick, once through the adapter model. "5 ms latency plus 1 ms jitter" is taken as
the round trip (2.5 ms + up to 0.5 ms each way), the figure a host measures; that link needs replies up to 7 ms
old, so its case runs the variant with ``acceptance.max_reply_age_ms = 7`` and gains checked for 7 ticks.
"""

from __future__ import annotations

import numpy as np
import pytest

from edc_bench.config import load_variant
from edc_bench.config.models import PARAMETER_NAMES, Variant
from edc_bench.population.batch import run_batch
from edc_bench.population.valves import draw_population
from edc_bench.runtime.gain_check import check_variant_gains
from edc_bench.sim.adapter import parse_adapter
from edc_bench.verdict.baseline import load_baseline
from edc_bench.verdict.classifier import default_classifier
from edc_bench.verdict.verdicts import Verdict

VALVES = 200


def slow_link_variant() -> Variant:
    """The default variant for a 5-6 ms round trip: replies up to 7 ms old, gains that keep margins at 7 ticks."""
    variant = load_variant("p-edc-default")
    return variant.model_copy(update={
        "controller": variant.controller.model_copy(update={"kp_v_per_mm": 0.2, "ki_v_per_mm_s": 8.0,
                                                            "kd_v_s_per_mm": 0.001}),
        "acceptance": variant.acceptance.model_copy(update={"max_reply_age_ms": 7.0}),
    })


def verdicts(variant: Variant, parameters: np.ndarray) -> np.ndarray:
    baseline = load_baseline(variant)
    rel = np.column_stack([parameters[:, PARAMETER_NAMES.index("af")] / baseline.af_v,
                           parameters[:, PARAMETER_NAMES.index("a1")] / baseline.a1_v_s_per_mm])
    return default_classifier(variant=variant).classify_many(rel)[0]


@pytest.mark.slow
@pytest.mark.parametrize(("link", "variant_of", "p95_rel", "max_rel"),
                         [("usb-fs", lambda: load_variant("p-edc-default"), 0.01, 0.02),
                          # the hard pump's a1 through usb-fs: p95 1.6 %, max 3.7 % (one valve of 200) with the
                          # per-valve jitter streams of 563fbfc (another realisation of the same jitter; the max of
                          # 200 is its tail): the bound is on the tail, the verdicts below are the point
                          ("usb-fs", lambda: load_variant("p-edc-hard"), 0.02, 0.04),
                          ("latency_ms=2.5,jitter_ms=0.5", slow_link_variant, 0.01, 0.02)],
                         ids=["usb-fs", "usb-fs-hard", "5ms-round-trip-1ms-jitter"])
def test_adapter_latency_leaves_identification_and_verdicts_alone(link, variant_of, p95_rel, max_rel) -> None:
    variant = variant_of()
    check_variant_gains(variant)  # the gains hold their margins at the link's delay
    valves = draw_population(variant, VALVES, seed=12)
    seeds = list(range(5000, 5000 + VALVES))
    instant = run_batch(variant, valves, seeds)
    delayed = run_batch(variant, valves, seeds, adapter=parse_adapter(link))
    ages = delayed.reply_age_ticks
    print(f"\n{link}: reply ages (ticks: replies) {ages}")
    fit = delayed.periods.at(delayed.periods.blocks).fit
    noise = delayed.periods.noise_v
    print(f"  model fit through the link: residual up to {np.max(fit.residual_rms_v) / noise:.2f}x the sensor "
          f"noise, its repeating part up to {np.max(fit.systematic_rms_v) / noise:.2f}x "
          f"(limit {variant.acceptance.max_residual_ratio:g}x)")
    assert instant.converged.all() and delayed.converged.all()
    # the link's timing is noise, not misfit: a pump the model fits still fits through it (#11's review found
    # faulty valves INVALID "does not fit" through usb-fs when the whole residual was judged)
    assert instant.model_fits.all() and delayed.model_fits.all()
    for name in ("af", "a1"):
        j = PARAMETER_NAMES.index(name)
        rel = delayed.parameters[:, j] / instant.parameters[:, j] - 1.0
        print(f"  {name}: difference mean {rel.mean():+.4%}, sd {rel.std():.4%}, "
              f"95th percentile |d| {np.percentile(np.abs(rel), 95):.4%}, max |d| {np.abs(rel).max():.4%}, "
              f"{int((np.abs(rel) > 0.01).sum())} of {VALVES} beyond 1 %")
        assert abs(rel.mean()) < 0.01, name
        assert np.percentile(np.abs(rel), 95) < p95_rel, name
        assert np.abs(rel).max() < max_rel, name
    v0, v1 = verdicts(variant, instant.parameters), verdicts(variant, delayed.parameters)
    differ = np.nonzero(v0 != v1)[0]
    print(f"  verdicts: {len(differ)} of {VALVES} differ: "
          + ", ".join(f"{v0[i]}->{v1[i]}" for i in differ))
    # a verdict may move only into or out of the marginal band, never between PASS and FAIL
    assert not any({v0[i], v1[i]} == {Verdict.PASS.value, Verdict.FAIL.value} for i in differ)
    assert len(differ) <= VALVES // 100
