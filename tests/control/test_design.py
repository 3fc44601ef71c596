"""One controller design: the loop's controller, the batch path and the perf floor are all built from it."""

from __future__ import annotations

import numpy as np
import pytest

from edc_bench.config import Variant
from edc_bench.config.models import PARAMETER_NAMES
from edc_bench.control.design import START_AT_ZERO, ControllerDesign
from edc_bench.control.law import derivative_filter_coefficients
from edc_bench.perf.compute import lean_tick
from edc_bench.physics.feedforward import nominal_parameters
from edc_bench.physics.valve import ValveSpec
from edc_bench.population.batch import run_batch


def test_design_takes_the_nominal_model_from_the_variants_physics(variant: Variant) -> None:
    design = ControllerDesign.from_variant(variant)
    assert design.nominal == tuple(nominal_parameters(variant))
    assert [PARAMETER_NAMES[i] for i in design.estimated] == list(variant.estimator.estimate)
    assert sorted(design.estimated + design.fixed) == list(range(len(PARAMETER_NAMES)))
    for j, i in enumerate(design.estimated):
        expected = 0.0 if PARAMETER_NAMES[i] in START_AT_ZERO else design.nominal[i] * design.scales[i]
        assert design.theta0[j] == expected
        assert design.prior_std[j] > 0


def test_the_loops_controller_starts_from_the_design(variant: Variant) -> None:
    design = ControllerDesign.from_variant(variant)
    ctl = design.controller(1.5)
    assert ctl.estimator.theta == list(design.theta0)
    assert [ctl.estimator.P[j][j] for j in range(len(design.theta0))] == pytest.approx(
        [s * s for s in design.prior_std])
    coefficients = ctl.pid.coefficients
    assert (coefficients.derivative_a, coefficients.derivative_b) == derivative_filter_coefficients(
        design.pid_gains, design.period_s)
    assert ctl.reversal_speed_mm_s == pytest.approx(design.reversal_speed_mm_s)
    assert len(ctl.table) == design.ticks
    assert ctl.reference.start_mm == 1.5


def test_a_changed_design_changes_the_floor_and_the_controller_alike(variant: Variant) -> None:
    """The floor reads the design, not the controller's private state: change the design, both follow."""
    base = ControllerDesign.from_variant(variant)
    changed = ControllerDesign(**{**base.__dict__, "theta0": tuple(t + 0.01 for t in base.theta0)})
    ctl, floor = changed.controller(1.0), lean_tick(changed, 1.0)
    x = 1.0
    for k in range(2500):
        u, u_floor = ctl.step(k, x), floor(k, x)
        assert u_floor == pytest.approx(u, abs=1e-9), k
        x = ctl.reference_mm
    assert base.controller(1.0).step(0, 1.0) != changed.controller(1.0).step(0, 1.0)


@pytest.mark.slow  # over 5 s each: the default suite's 5 minutes (CI's slow pass runs it)
def test_batch_path_identifies_like_the_loop_from_the_same_design(variant: Variant) -> None:
    """On the noise-free model plant the only difference left is the codec's 1 um / 1 mV quantisation in the loop.

    (The noisy, stiction case is held to the documented 1 % by tests/population/test_batch.py.)
    """
    from edc_bench.bench import run_simulated_test

    valve = ValveSpec(variant.valve.presets["worn"].clearance_mm, label="worn")
    loop = run_simulated_test(variant, valve, seed=0, stiction=False, sensor_noise=False, check_gains=False,
                              classify=False)
    batch = run_batch(variant, [valve], [0], stiction=False, sensor_noise=False)
    for name in ("af", "a1", "a0", "b"):
        assert batch.feature(name)[0] == pytest.approx(loop.parameters[name].value, rel=1e-3), name
    # the period fit's normal equations see the codec's quantisation in the loop only: equal to 0.1 %
    assert np.isclose(batch.condition_number, loop.identification.condition_number, rtol=1e-3)


@pytest.mark.parametrize("kind", ["rls", "gradient"])
def test_the_estimators_law_is_a_value_however_the_variant_was_made(variant: Variant, kind: str) -> None:
    """A variant copied with model_copy(update=...) keeps the plain word (pydantic does not validate updates): the
    design makes it the EstimatorKind the loop, the batch and the perf floor compare by identity (the perf
    figure 'PID + feedforward + rls' once measured the gradient law that way)."""
    from edc_bench.config.models import EstimatorKind

    copied = variant.model_copy(update={"estimator": variant.estimator.model_copy(update={"kind": kind})})
    assert ControllerDesign.from_variant(copied).estimator_kind is EstimatorKind(kind)
