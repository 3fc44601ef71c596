"""Build the bench controller of a variant: reference, PID, estimator, FEL."""

from __future__ import annotations

import math

from edc_bench.config.models import PARAMETER_NAMES, Variant
from edc_bench.control.estimators import Estimator, NormalisedGradient, RecursiveLeastSquares
from edc_bench.control.fel import FelController
from edc_bench.control.pid import Pid, PidGains
from edc_bench.control.reference import Reference, Tone
from edc_bench.sim.plant import PlantParameters
from edc_bench.sim.valve import FeedforwardParameters, ValveSpec, feedforward_truth, plant_parameters

# The diagnosis features start from zero, as in the paper (G1 = 0 at first):
# no prior pulls a worn valve towards "new".
_START_AT_ZERO = ("a1", "af")


def nominal_plant(variant: Variant) -> PlantParameters:
    """The variant's plant with a nominal new valve (no spread)."""
    preset = variant.valve.presets["new"]
    return plant_parameters(variant, ValveSpec(preset.clearance_mm, preset.roughness, label="nominal new"))


def nominal_parameters(variant: Variant) -> FeedforwardParameters:
    """Feedforward parameters of the nominal plant, from the data-sheet physics."""
    return feedforward_truth(nominal_plant(variant))


def reference_for(variant: Variant, start_mm: float) -> Reference:
    """The variant's reference, starting at the measured rack position."""
    ex = variant.excitation
    tones = tuple(Tone(t.frequency_hz, t.amplitude_mm, math.radians(t.phase_deg)) for t in ex.active_tones)
    return Reference(start_mm, variant.rack.mid_stroke_mm, tones, ex.move_s, ex.fade_s)


def regressor_scales(variant: Variant) -> list[float]:
    """Typical magnitude of each regressor [r''', r'', r', r, 1, sgn]."""
    tones = variant.excitation.active_tones
    w = [2 * math.pi * t.frequency_hz for t in tones]
    a = [t.amplitude_mm for t in tones]
    return [
        sum(ai * wi**3 for ai, wi in zip(a, w, strict=True)),
        sum(ai * wi**2 for ai, wi in zip(a, w, strict=True)),
        sum(ai * wi for ai, wi in zip(a, w, strict=True)),
        variant.rack.mid_stroke_mm,
        1.0,
        1.0,
    ]


def build_estimator(variant: Variant, theta0: list[float], prior_std: list[float]) -> Estimator:
    """The estimator the variant asks for, on normalised parameters."""
    est = variant.estimator
    if est.kind == "rls":
        return RecursiveLeastSquares(theta0, prior_std, est.forgetting_factor)
    gains = est.gradient_gains_per_s
    per_param = [gains[n] for n in est.estimate] if isinstance(gains, dict) else [gains] * len(est.estimate)
    return NormalisedGradient(theta0, per_param, variant.controller.period_s)


def build_controller(variant: Variant, start_mm: float) -> FelController:
    """The bench controller for one test.

    Parameters
    ----------
    variant : Variant
        Pump variant (excitation, controller, estimator sections).
    start_mm : float
        Rack position measured before the test starts.
    """
    c = variant.controller
    reference = reference_for(variant, start_mm)
    pid = Pid(PidGains(c.kp_v_per_mm, c.ki_v_per_mm_s, c.kd_v_s_per_mm, c.derivative_filter_hz),
              c.period_s, variant.rig.drive_limit_v)
    nominal = list(nominal_parameters(variant))
    scales = regressor_scales(variant)
    estimated = [PARAMETER_NAMES.index(n) for n in variant.estimator.estimate]
    theta0 = [(0.0 if PARAMETER_NAMES[i] in _START_AT_ZERO else nominal[i]) * scales[i] for i in estimated]
    # prior spread: a few times the nominal magnitude, so the data decide
    prior_std = [max(abs(nominal[i] * scales[i]), 1e-9) * 3.0 * variant.estimator.initial_std_rel for i in estimated]
    return FelController(
        reference, pid, build_estimator(variant, theta0, prior_std),
        nominal=nominal, estimated=estimated, scales=scales, drive_limit_v=variant.rig.drive_limit_v,
        period_s=c.period_s, adapt_from_s=variant.excitation.move_s,
        reversal_speed_mm_s=variant.estimator.reversal_exclusion * reference.peak_velocity_mm_s,
        ticks=int(round(variant.excitation.duration_s / c.period_s)),
    )
