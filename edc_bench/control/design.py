"""One controller design per variant: everything the bench controller is built from.

:class:`ControllerDesign` is derived once from a variant's physics (the
nominal feedforward parameters), its excitation, its PID gains and its
estimator settings. The loop's :class:`~edc_bench.control.fel.FelController`,
the batch path (:mod:`edc_bench.population.batch`) and the perf floor
(:mod:`edc_bench.perf.compute`) all take their reference, PID coefficients,
starting estimates, prior, regressor scales and parameter split from it,
so none of them decides these on its own; ``tests/control/test_design.py``
holds them to it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from edc_bench.config.models import PARAMETER_NAMES, EstimatorKind, Variant
from edc_bench.control.coil import averaging_window_s
from edc_bench.control.estimators import Estimator, NormalisedGradient, RecursiveLeastSquares
from edc_bench.control.fel import FelController
from edc_bench.control import law
from edc_bench.control.law import derivative_filter_coefficients
from edc_bench.control.pid import Pid, PidGains
from edc_bench.control.reference import Reference, Tone
from edc_bench.physics.feedforward import nominal_parameters

#: The diagnosis features start from zero, as in the paper (G1 = 0 at first):
#: no prior pulls a worn valve towards "new".
START_AT_ZERO = ("a1", "af")
#: Prior standard deviation of an estimated parameter, in multiples of its nominal magnitude: wide, so the data decide.
PRIOR_STD_PER_NOMINAL = 3.0


@dataclass(frozen=True)
class ControllerDesign:
    """The bench controller of one variant, as numbers.

    Attributes
    ----------
    period_s : float
        Tick period T.
    ticks : int
        Ticks of a full-length test.
    drive_limit_v : float
        The drive (and the PID's own output) saturates at +/- this.
    pid_gains : PidGains
        Feedback gains.
    nominal : tuple of float
        ``[a3, a2, a1, a0, b, af]`` of the variant's nominal plant (physical
        units); parameters that are not estimated stay at these values.
    scales : tuple of float
        Typical magnitude of each regressor ``[r''', r'', r', r, 1, sgn r']``;
        the estimator works on ``W_i / scale_i``, so its parameters are
        ``a_i * scale_i``.
    estimated : tuple of int
        Indices into the six of the parameters the estimator adapts, in its order.
    theta0 : tuple of float
        Starting estimates of the estimated parameters (normalised).
    prior_std : tuple of float
        Their prior standard deviations (normalised; RLS's P0 = diag(std^2)).
    estimator_kind : EstimatorKind
        Recursive least squares or a gradient law.
    forgetting_factor : float
        RLS's lambda.
    gradient_gains_per_s : tuple of float
        The gradient law's gain per estimated (normalised) parameter.
    mid_mm, tones, move_s, fade_s :
        The reference: move to ``mid_mm`` in ``move_s``, then the tones faded in over ``fade_s``.
    reversal_exclusion : float
        No adaptation while |r'| is below this fraction of its peak (stick windows).
    amplifier_gain : float
        k_A, coil volts per volt of drive (the coil estimator's).
    reference_resistance_ohm : float
        The reference coil's resistance (the variant's nominal, 20 degC): the parameters are referred to it.
    """

    period_s: float
    ticks: int
    drive_limit_v: float
    pid_gains: PidGains
    nominal: tuple[float, ...]
    scales: tuple[float, ...]
    estimated: tuple[int, ...]
    theta0: tuple[float, ...]
    prior_std: tuple[float, ...]
    estimator_kind: EstimatorKind
    forgetting_factor: float
    gradient_gains_per_s: tuple[float, ...]
    mid_mm: float
    tones: tuple[Tone, ...]
    move_s: float
    fade_s: float
    reversal_exclusion: float
    amplifier_gain: float = 1.0
    reference_resistance_ohm: float = 1.0

    @classmethod
    def from_variant(cls, variant: Variant) -> ControllerDesign:
        """The design of ``variant``'s controller (its physics, excitation, gains and estimator)."""
        c, ex, est = variant.controller, variant.excitation, variant.estimator
        nominal = tuple(float(v) for v in nominal_parameters(variant))
        tones = tuple(Tone(t.frequency_hz, t.amplitude_mm, math.radians(t.phase_deg)) for t in ex.active_tones)
        scales = regressor_scales(tones, variant.rack.mid_stroke_mm)
        estimated = tuple(PARAMETER_NAMES.index(n) for n in est.estimate)
        theta0 = tuple((0.0 if PARAMETER_NAMES[i] in START_AT_ZERO else nominal[i]) * scales[i] for i in estimated)
        prior_std = tuple(max(abs(nominal[i] * scales[i]), 1e-9) * PRIOR_STD_PER_NOMINAL * est.initial_std_rel
                          for i in estimated)
        gains = est.gradient_gains_per_s
        per_param = tuple(float(gains[n]) for n in est.estimate) if isinstance(gains, dict) \
            else (float(gains),) * len(estimated)
        return cls(
            period_s=c.period_s, ticks=int(round(ex.duration_s / c.period_s)), drive_limit_v=variant.rig.drive_limit_v,
            pid_gains=PidGains(c.kp_v_per_mm, c.ki_v_per_mm_s, c.kd_v_s_per_mm, c.derivative_filter_hz),
            nominal=nominal, scales=scales, estimated=estimated, theta0=theta0, prior_std=prior_std,
            # EstimatorKind(...): a variant copied with model_copy(update=...) keeps a plain str there
            estimator_kind=EstimatorKind(est.kind), forgetting_factor=est.forgetting_factor,
            gradient_gains_per_s=per_param,
            mid_mm=variant.rack.mid_stroke_mm, tones=tones, move_s=ex.move_s, fade_s=ex.fade_s,
            reversal_exclusion=est.reversal_exclusion, amplifier_gain=variant.coil.amplifier_gain,
            reference_resistance_ohm=variant.coil.resistance_ohm,
        )

    @property
    def fixed(self) -> tuple[int, ...]:
        """Indices of the parameters held at their nominal value."""
        return tuple(i for i in range(len(PARAMETER_NAMES)) if i not in self.estimated)

    @property
    def coil_window_ticks(self) -> int:
        """Ticks the coil's resistance is averaged over before use: the excitation's longest period."""
        return max(1, round(averaging_window_s(t.frequency_hz for t in self.tones) / self.period_s))

    @property
    def adapt_from_s(self) -> float:
        """No adaptation before this time (the move to mid-stroke)."""
        return self.move_s

    @property
    def reversal_speed_mm_s(self) -> float:
        """No adaptation while |r'| is below this (the stick windows at reversals)."""
        return self.reversal_exclusion * self.reference(0.0).peak_velocity_mm_s

    @property
    def derivative_filter(self) -> tuple[float, float]:
        """The PID's filtered-derivative coefficients ``(a, b)``."""
        return derivative_filter_coefficients(self.pid_gains, self.period_s)

    def composition(self) -> law.Composition:
        """How each tick is composed (:func:`edc_bench.control.law.feedforward_tick`): the one the loop's controller,
        the batch path and the benchmark's floor all use."""
        return law.Composition(self.estimated, tuple(1.0 / self.scales[i] for i in self.estimated),
                               tuple((i, self.nominal[i]) for i in self.fixed), self.drive_limit_v,
                               self.adapt_from_s, self.reversal_speed_mm_s)

    def reference(self, start_mm: float) -> Reference:
        """The test's reference, starting at the measured rack position ``start_mm``."""
        return Reference(start_mm, self.mid_mm, self.tones, self.move_s, self.fade_s)

    def pid(self) -> Pid:
        """A fresh PID."""
        return Pid(self.pid_gains, self.period_s, self.drive_limit_v)

    def estimator(self) -> Estimator:
        """A fresh estimator at the starting estimates."""
        if self.estimator_kind is EstimatorKind.RLS:
            return RecursiveLeastSquares(self.theta0, self.prior_std, self.forgetting_factor)
        return NormalisedGradient(self.theta0, self.gradient_gains_per_s, self.period_s)

    def controller(self, start_mm: float) -> FelController:
        """The bench controller for one test, with the rack measured at ``start_mm``."""
        return FelController(self, self.reference(start_mm), self.pid(), self.estimator())


def regressor_scales(tones: tuple[Tone, ...], mid_mm: float) -> tuple[float, ...]:
    """Typical magnitude of each regressor ``[r''', r'', r', r, 1, sgn r']`` for an excitation about ``mid_mm``."""
    w = [2 * math.pi * t.frequency_hz for t in tones]
    a = [t.amplitude_mm for t in tones]
    return (
        sum(ai * wi**3 for ai, wi in zip(a, w, strict=True)),
        sum(ai * wi**2 for ai, wi in zip(a, w, strict=True)),
        sum(ai * wi for ai, wi in zip(a, w, strict=True)),
        mid_mm,
        1.0,
        1.0,
    )


def build_controller(variant: Variant, start_mm: float) -> FelController:
    """The bench controller of ``variant`` for one test (:meth:`ControllerDesign.controller`)."""
    return ControllerDesign.from_variant(variant).controller(start_mm)
