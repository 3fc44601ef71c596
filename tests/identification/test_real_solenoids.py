"""Issue #11: identification that holds on real solenoids, and a verdict as soon as the numbers are known.

Reproduced first: on p-edc-hard (a force constant +/-10 % over the swing, Stribeck friction, damping ratio
0.3) the regression on the reference put a1 at -34 % and af at +12 % on a new valve and never settled, so
every test was INVALID "not converged". These tests hold the period fit to the issue's figures.
"""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from edc_bench.bench import run_simulated_test
from edc_bench.config import load_variant
from edc_bench.experiments.studies import with_gain_variation
from edc_bench.physics.valve import nominal_plant, parse_valve_spec, plant_parameters
from edc_bench.population.batch import run_batch
from edc_bench.sim.plant import Plant
from edc_bench.verdict.verdicts import Verdict

VALVES = ("new", "worn", "faulty")
SEEDS = (0, 1, 2)


@pytest.fixture(scope="module")
def hard():
    return load_variant("p-edc-hard")


# ---------------------------------------------------------------------------------------------- the plant


def test_the_hard_variant_is_what_the_issue_asks_for(hard) -> None:
    p = nominal_plant(hard)
    k_eff = p.net_stiffness_n_per_mm - p.magnetic_stiffness_from_slope_n_per_mm  # linearised at mid-stroke
    zeta = p.damping_n_s_per_mm / (2 * math.sqrt(k_eff * p.mass_n_s2_per_mm))
    assert 0.25 <= zeta <= 0.35
    swing = sum(t.amplitude_mm for t in hard.excitation.active_tones)
    low, high = (p.force_constant_at(hard.rack.mid_stroke_mm + s * swing) / p.force_constant_n_per_a for s in (-1, 1))
    assert low == pytest.approx(0.9, abs=0.01) and high == pytest.approx(1.1, abs=0.01)
    assert p.sliding_friction_n(0.0) == pytest.approx(p.stiction_friction_n)
    assert p.sliding_friction_n(20.0) == pytest.approx(p.coulomb_friction_n, rel=1e-9)
    assert p.coulomb_friction_n < p.sliding_friction_n(1.0) < p.stiction_friction_n
    # the existing variants keep the linear model
    for name in ("p-edc-default", "p-edc-long", "paper"):
        assert nominal_plant(load_variant(name)).linear


def test_a_position_dependent_force_constant_holds_the_rack_where_k_i_x_i_balances_the_spring(hard) -> None:
    params = replace(plant_parameters(hard, parse_valve_spec("new", hard), stiction=False),
                     temperature_coefficient_per_k=0.0, coulomb_friction_n=0.0, stiction_friction_n=0.0)
    plant = Plant(params, position_mm=10.0)
    plant.stuck = False
    drive_v = 2.0
    plant.set_drive_v(drive_v)
    for _ in range(20):  # 2 s: the lightly damped rack settles
        plant.advance(1000)
    current_a = params.amplifier_gain * drive_v / params.resistance_ohm
    x = plant.x_mm
    # from first principles: k_i (1 + s (x - x_m)) i = k' x + F_pre
    pull = params.force_constant_at(x) * current_a
    assert pull == pytest.approx(params.net_stiffness_n_per_mm * x + params.preload_n, rel=1e-4)
    assert abs(x - params.equilibrium_mm(drive_v)) > 0.1  # the constant-k_i answer is measurably elsewhere


def test_batch_plant_steps_the_nonlinear_plant_as_the_simulated_rig_does(hard) -> None:
    from edc_bench.population.batch import _VectorPlant

    valve = parse_valve_spec("faulty", hard)
    single = Plant(plant_parameters(hard, valve), quantum_s=1e-4, position_mm=0.0)
    vector = _VectorPlant(hard, [valve], True, 1e-3)
    t = np.arange(3000) * 1e-3
    drive = 2.0 + 1.5 * np.sin(2 * np.pi * 0.7 * t)  # slow reversals: stick, Stribeck breakaway, sliding
    xs, xv = [], []
    for u in drive:
        single.set_drive_v(float(u))
        single.advance(10)
        vector.advance_period(np.array([u]))
        vector.add_heat(1e-3)  # the coil warms in both
        xs.append(single.x_mm)
        xv.append(float(vector.x[0]))
    assert np.max(np.abs(np.array(xs) - np.array(xv))) < 2e-3  # mm, over a 7 mm travel


# ------------------------------------------------------------------------------------- identification


@pytest.fixture(scope="module")
def hard_batch(hard):
    """New, worn and faulty valves, three seeds each, on the hard variant (batch path, full length)."""
    valves = [parse_valve_spec(v, hard) for v in VALVES for _ in SEEDS]
    seeds = [s for _ in VALVES for s in SEEDS]
    return run_batch(hard, valves, seeds)


def test_hard_variant_af_within_5_and_a1_within_10_percent_converged_for_every_valve_and_seed(hard_batch) -> None:
    error = hard_batch.parameters / hard_batch.truth - 1.0
    af, a1 = error[:, 5], error[:, 2]
    print("af error %", np.round(af * 100, 2), "a1 error %", np.round(a1 * 100, 2))
    assert np.all(np.abs(af) < 0.05) and np.all(np.abs(a1) < 0.10)
    assert hard_batch.converged.all() and hard_batch.model_fits.all()


def test_three_seeds_spread_less_than_a_fifth_of_the_new_to_worn_difference(hard_batch) -> None:
    for column in (5, 2):  # af, a1
        values = hard_batch.parameters[:, column].reshape(len(VALVES), len(SEEDS))
        new_to_worn = values[1].mean() - values[0].mean()
        for row in values:
            assert np.ptp(row) < new_to_worn / 5, (column, row, new_to_worn)


def test_the_loop_identifies_the_hard_variant_as_the_batch_path_does(hard, hard_batch) -> None:
    loop = run_simulated_test(hard, "worn", 1, full_length=True)
    assert loop.converged and loop.judgement.identification.model_fit.fits
    for name, column in (("af", 5), ("a1", 2)):
        assert loop.parameters[name].value == pytest.approx(hard_batch.parameters[4, column], rel=0.01), name
        assert abs(loop.parameters[name].error_rel) < (0.05 if name == "af" else 0.10)
    fit = loop.judgement.identification.model_fit
    # the solenoid's gain variation is seen (+/-10 % in the plant, first-order estimate)
    assert 0.05 < fit.gain_variation_rel < 0.2
    # and the model fit is measured alike: the residual and its part that repeats from period to period
    batch_fit = hard_batch.periods.at(hard_batch.periods.blocks).fit
    assert fit.residual_rms_v == pytest.approx(batch_fit.residual_rms_v[4], rel=0.05)
    assert fit.systematic_rms_v == pytest.approx(batch_fit.systematic_rms_v[4], rel=0.1)


@pytest.mark.slow  # 10-16 s: the default suite stays under 5 minutes; CI's slow pass runs it
def test_default_plant_within_2_and_5_percent_and_the_model_matched_plant_within_1_1_percent() -> None:
    variant = load_variant("p-edc-default")
    for valve in VALVES:
        result = run_simulated_test(variant, valve, 3)
        assert abs(result.parameters["af"].error_rel) < 0.02 and abs(result.parameters["a1"].error_rel) < 0.05
    # the model-matched plant: no noise, so one seed says it all; a new valve of p-edc-long is the closest to the
    # bound (af -1.00 % at 30 s, docs/bench-test.md, "Measured accuracy"; -0.99 % before the estimate was the core
    # rows' fit: the smoothing's bias on it, not the friction's, which the model plant does not have)
    for name, valve in (("p-edc-default", "worn"), ("p-edc-default", "new"), ("p-edc-long", "new")):
        matched = run_simulated_test(load_variant(name), valve, 3, stiction=False, sensor_noise=False,
                                     full_length=True)
        errors = {parameter: entry.error_rel
                  for parameter, entry in matched.parameters.items() if entry.estimated}
        print(name, valve, "model-matched plant, 30 s:", {p: f"{e:+.2%}" for p, e in errors.items()})
        for parameter, error in errors.items():
            assert abs(error) < 0.011, (name, valve, parameter, error)


# ------------------------------------------------------------------------------------------- model fit


@pytest.mark.parametrize("variation_rel", [pytest.param(0.30, marks=pytest.mark.slow), -0.30], ids=["+30%", "-30%"])
def test_a_plant_the_model_cannot_fit_ends_invalid_with_the_model_fit_reason_early(hard, variation_rel: float) -> None:
    """Every valve, the faulty one included: with its friction not yet learnt it sticks and lags its reference on
    this pump (more than 1 mm off for about 50 ms at a time), stick-slip that the tracking check must not take for
    a stuck rack or sensor (engine/tracking.py)."""
    variant = with_gain_variation(hard, variation_rel)
    for valve in VALVES:
        result = run_simulated_test(variant, valve, 0, nominal_baseline=True)
        assert result.verdict == Verdict.INVALID
        reason = next(r for r in result.reasons if "model" in r)
        assert reason.startswith("the feedforward model does not fit this pump: ")
        assert "a longer test will not help" in reason
        assert not any(r.startswith("not converged") for r in result.reasons)
        assert result.stop.reason == "model does not fit"
        assert result.stop.time_s < variant.excitation.duration_s
        assert not result.judgement.identification.model_fit.fits
        # the stick-slip the tracking check must ride out (docs/bench-test.md)
        if valve == "faulty" and variation_rel > 0:
            limit_mm = variant.acceptance.max_tracking_error_mm
            longest = {}
            for off_mm in (limit_mm / 2, limit_mm):
                off = np.abs(result.trace["reference_mm"] - result.trace["position_mm"]) > off_mm
                edges = np.flatnonzero(np.diff(np.r_[0, off.astype(np.int8), 0]))
                longest[off_mm] = int((edges[1::2] - edges[::2]).max()) if len(edges) else 0
            print(f"+30 % faulty: longest runs off its reference (mm: ticks) {longest}")
            assert longest[limit_mm / 2] > 0  # it does stick and lag
            assert longest[limit_mm] < variant.acceptance.tracking_error_ticks // 2 + 1


@pytest.mark.slow
def test_a_pump_beyond_the_hard_variant_is_judged_only_where_it_is_identified_as_well() -> None:
    """Found by #11's second review: with the first-order model alone, pumps whose force constant varied by +22 % or
    -15 % over the swing passed the model-fit rule with a1 up to 10.6 % and 12.5 % off (the hard variant is held to
    10 %). With the friction's second-order term the judged ones are identified as well as the hard variant, or
    (#37 item 3: a misfit widens the interval or refuses, never neither) their interval holds the truth; the
    others are INVALID "does not fit", and every valve on a +15 % pump is still judged (docs/method.md, "Beyond the
    first order"; all rows: python docs/regenerate.py --measure method-gain-sweep)."""
    from edc_bench.experiments.studies import gain_sweep

    rows = gain_sweep(None, [0.15, 0.22, -0.15], 60, 5)
    for row in rows:
        print(row)
        if row.judged:
            assert row.af_error_max < 0.10 and row.a1_error_max < 0.20, row  # nothing wild is judged
        assert row.beyond_unflagged == 0, row
        assert row.faulty_passed == 0, row
        assert row.judged + row.misfit == row.valves, row  # the rest is INVALID for the model fit
    assert rows[0].judged == rows[0].valves


def test_every_record_carries_the_model_fit(tmp_path: Path) -> None:
    import json

    from edc_bench.records.record import write_record

    result = run_simulated_test(load_variant("p-edc-hard"), "new", 0)
    doc = json.loads((write_record(result, tmp_path, figure=False) / "record.json").read_text())
    fit = doc["identification"]["model_fit"]
    assert fit["fits"] is True and fit["problems"] == []
    assert 0.3 < fit["residual_ratio"] < doc["config"]["acceptance"]["max_residual_ratio"]
    assert 0 <= fit["systematic_ratio"] < fit["residual_ratio"]
    assert fit["systematic_rms_v"] == pytest.approx(fit["systematic_ratio"] * fit["expected_noise_v"])
    assert set(fit["spread_rel"]) == {"af", "a1"}
    assert doc["stop"]["reason"] == "verdict certain" and doc["stop"]["max_s"] == 30.0


# ---------------------------------------------------------------------------------------- early stop


def test_an_early_stop_gives_the_full_length_verdict_on_the_hard_variant(hard) -> None:
    for valve in VALVES:
        early = run_simulated_test(hard, valve, 2)
        assert early.stop.reason == "verdict certain" and early.stop.time_s <= 12.0
        assert early.verdict in (Verdict.PASS, Verdict.FAIL)
        assert (early.verdict == Verdict.FAIL) == (valve != "new")
        assert abs(early.parameters["af"].error_rel) < 0.05 and abs(early.parameters["a1"].error_rel) < 0.10


def test_a_test_not_classified_runs_its_full_length_and_says_why() -> None:
    result = run_simulated_test(load_variant(), "new", 0, classify=False)
    assert result.timing.ticks == 30_000
    assert result.stop.reason == "full length" and "not classified" in result.stop.why_full_length


@pytest.mark.slow
@pytest.mark.parametrize("name", ["p-edc-default", "p-edc-hard"])
def test_the_early_interval_holds_what_the_full_length_test_finds(name: str) -> None:
    """The 99 % box the early stop judges by, after three periods, through a USB adapter's jitter: does it hold
    the 30 s estimate? With the normal quantile on the spread of three periods it held too few; with Student's t
    for the spread's two degrees of freedom, it must hold it for 98 % of valves (docs/bench-test.md prints both
    counts: `python docs/regenerate.py --measure bench-test-early-interval`).
    (It is the test's own noise; the identification's bias, measured in docs/bench-test.md, is no part of it.)"""
    from edc_bench.population.valves import draw_population
    from edc_bench.sim.adapter import parse_adapter
    from edc_bench.verdict.baseline import load_baseline
    from edc_bench.verdict.early_stop import Interval, relative_box

    variant = load_variant(name)
    valves = draw_population(variant, 100, seed=3)
    result = run_batch(variant, valves, list(range(100)), adapter=parse_adapter("usb-fs"))
    baseline = load_baseline(variant, station=False)
    base = np.array([baseline.af_v, baseline.a1_v_s_per_mm])
    at = result.periods.at(3)
    box = relative_box(at.parameters[:, [5, 2]], at.fit, base, Interval.of(variant, result.periods.blocks))
    centre, half_width = box.centre, box.statistical  # the test's own noise
    full = result.parameters[:, [5, 2]] / base
    inside = np.all(np.abs(full - centre) <= half_width, axis=1)
    print(f"{name}: the full-length estimate inside the early box for {inside.sum()} of 100 valves")
    assert inside.mean() >= 0.98


@pytest.mark.slow
def test_time_to_verdict_over_210_valves_median_10_s_p95_20_s_with_the_full_lengths_accuracy() -> None:
    from edc_bench.experiments.studies import time_to_verdict

    report = time_to_verdict(None, ["p-edc-default", "p-edc-long", "p-edc-hard"], 70, 777)
    print(report.per_variant, report.early, report.full)
    assert report.valves == 210
    assert report.median_s <= 10.0 + 0.1 and report.p95_s <= 20.0
    early, full = report.early, report.full
    assert early.accuracy_outside_band >= full.accuracy_outside_band
    assert early.marginal_fraction <= full.marginal_fraction


@pytest.mark.slow  # the default suite's 5 minutes; CI's slow pass runs it
@pytest.mark.parametrize("name", ["p-edc-default", "p-edc-hard", "p-edc-long"])
def test_a_pump_the_model_fits_is_judged_through_a_usb_adapter(name: str) -> None:
    """A USB adapter's timing jitter is noise, not misfit. Found by #11's review: through usb-fs (0.5 ms jitter,
    1 ms USB frames) a faulty valve's whole residual reached 5.2-5.9x the sensor noise (2.5-3.7x without latency)
    and the test was INVALID, 'the feedforward model does not fit this pump', though af and a1 stayed within 1 %.
    The misfit is now judged by the residual's part that repeats from period to period: 1.6-3.7x here."""
    variant = load_variant(name)
    for valve in VALVES:
        lockstep = run_simulated_test(variant, valve, 0)
        usb = run_simulated_test(variant, valve, 0, adapter="usb-fs")
        fit = usb.judgement.identification.model_fit
        print(f"{name} {valve}: residual {fit.residual_ratio:.2f}x, repeating {fit.systematic_ratio:.2f}x; "
              f"{lockstep.verdict.value} -> {usb.verdict.value} at {usb.stop.time_s:.1f} s")
        assert fit.fits, usb.reasons
        assert fit.systematic_ratio < 0.8 * variant.acceptance.max_residual_ratio  # a margin, not a coin toss
        assert usb.verdict == lockstep.verdict != Verdict.INVALID
