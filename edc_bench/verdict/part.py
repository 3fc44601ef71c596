"""Which part of the fuel-injection module is at fault: the valve, the control rack or the rack-travel sensor.

:func:`diagnose_parts` holds each signature a test measured (:mod:`edc_bench.identification.signatures`, and the
motion parameters against the baseline's) to its limit (the variant's ``[diagnosis.parts]``) and names the part:

- the **rack-travel sensor** first: a reading that drops out, spikes, is noisier than the sensor's stated noise, or
  reads the rack at rest off its stop, or scales every motion parameter (a2, a0: volts per millimetre of the
  reading) together, or bends over a few millimetres more than the rack's friction there could make it (a step in
  its characteristic, which the rack's figures alone would take for a bind or a slope). Such a reading biases every
  figure of the test, the valve's too: the valve is not judged;
- the **rack**, where the sensor's reading is sound: friction that rises at one place (a bind) or along the stroke
  (a slope). A valve's friction is the same wherever the rack is; the valve is not judged ("retest after the rack is
  free"), since the valve's own friction cannot be told from the rack's there;
- **valve or rack**: friction above a new valve's that is the same along the whole stroke is a worn valve or a rack
  that drags evenly; this test cannot tell them apart, and says so;
- otherwise nothing beyond the valve: its verdict stands alone.

The result is one typed value, :class:`PartDiagnosis`, from which the advice, ``--json``, the record and the history
speak (:mod:`edc_bench.verdict.part_sections` holds its shape, a leaf the record's schema reads).
"""

from __future__ import annotations

import math
from collections.abc import Mapping

from edc_bench.config.models import PartLimits, Variant
from edc_bench.identification.signatures import FrictionProfile, PumpSignatures, ReadingStatistics
from edc_bench.verdict.baseline import Baseline
from edc_bench.verdict.part_sections import (
    FrictionProfileSummary,
    Part,
    PartDiagnosis,
    PartFinding,
    ReadingSummary,
    Signature,
)
from edc_bench.verdict.sections import ParameterEstimate

#: A signature counts only this many standard errors clear of nothing as well as beyond its limit.
SIGNIFICANCE = 3.0
#: Beyond this variation of the solenoid's pull over the swing (+/-, as the spring's Delta^2 term gives it) the
#: friction along the stroke is not judged: the correction for it leaves tilts of tens of per cent in a sound
#: rack's profile (a +/-20 % solenoid: -24 %), and at +/-25 % the model does not fit the pump at all. The shipped
#: variants' solenoids vary +/-10 % at the most (p-edc-hard).
PROFILE_GAIN_LIMIT_REL = 0.15
#: A bend alike in both directions this share of the friction's rise or more is a sensor that reads unevenly, not
#: the rack's friction leaking into it (:func:`_uneven_finding`).
UNEVEN_SHARE = 0.7
#: What this test's excitation does not identify, said in every diagnosis.
NOT_IDENTIFIED = ("friction that differs between the directions of travel (it differs from the spring's preload "
                  "line only by a straight line)",)


def _outside_swing(profile: FrictionProfileSummary | None, stroke_mm: float) -> str:
    if profile is None or not profile.positions_mm:
        return "the rack's friction along the stroke (too little of the test slid)"
    return (f"the rack's friction outside {profile.positions_mm[0]:.1f}-{profile.positions_mm[-1]:.1f} mm of its "
            f"{stroke_mm:g} mm stroke (the test's swing)")


def _motion_ratio(parameters: Mapping[str, ParameterEstimate], baseline: Baseline | None,
                  key: str, name: str) -> tuple[float, float] | None:
    """The test's parameter over the baseline's mean, and that ratio's spread between new valves (None: not known)."""
    if baseline is None:
        return None
    held = baseline.motion(key)
    estimate = parameters.get(name)
    if held is None or estimate is None or not estimate.estimated or estimate.value is None:
        return None
    mean, sd, _ = held
    if not (math.isfinite(estimate.value) and estimate.value > 0 and mean > 0):
        return None
    return estimate.value / mean, abs(sd / mean)


def _reading_findings(limits: PartLimits, reading: ReadingStatistics, fit_trusted: bool) -> list[PartFinding]:
    """The sensor's own statistics (its dropouts, spikes, noise) and its reading at rest, against their limits; the
    noise (about the smoothed trajectory) only where the rack moved as the test meant it to (an unstable loop's own
    shaking is no sensor's noise)."""
    noise = reading.noise_ratio
    found = [
        PartFinding(signature=Signature.SENSOR_DROPOUTS, part=Part.SENSOR, figure=reading.dropouts,
                    limit=limits.sensor_dropouts, beyond=reading.dropouts >= limits.sensor_dropouts),
        PartFinding(signature=Signature.SENSOR_SPIKES, part=Part.SENSOR, figure=reading.spikes,
                    limit=limits.sensor_spikes, beyond=reading.spikes >= limits.sensor_spikes),
        PartFinding(signature=Signature.SENSOR_NOISE, part=Part.SENSOR, figure=noise, limit=limits.sensor_noise_ratio,
                    unit="x", beyond=fit_trusted and math.isfinite(noise) and noise > limits.sensor_noise_ratio),
    ]
    if math.isfinite(reading.rest_mm):
        found.append(PartFinding(signature=Signature.SENSOR_ZERO, part=Part.SENSOR, figure=reading.rest_mm,
                                 limit=limits.sensor_offset_mm, unit="mm",
                                 beyond=abs(reading.rest_mm) > limits.sensor_offset_mm))
    return found


def _rack_findings(limits: PartLimits, profile: FrictionProfile, af0: float) -> list[PartFinding]:
    """The rack's friction along the swing: its highest place and its slope, in shares of a new valve's friction."""
    return [
        PartFinding(signature=Signature.RACK_BIND, part=Part.RACK, figure=profile.peak_v / af0,
                    limit=limits.rack_bind_rel, at_mm=profile.peak_at_mm, std=profile.peak_std_v / af0,
                    beyond=profile.peak_v / af0 > limits.rack_bind_rel
                    and profile.peak_v > SIGNIFICANCE * profile.peak_std_v),
        PartFinding(signature=Signature.RACK_SLOPE, part=Part.RACK, figure=profile.slope_v / af0,
                    limit=limits.rack_slope_rel, std=profile.slope_std_v / af0,
                    beyond=abs(profile.slope_v) / af0 > limits.rack_slope_rel
                    and abs(profile.slope_v) > SIGNIFICANCE * profile.slope_std_v),
    ]


def _uneven_finding(profile: FrictionProfile, rack: list[PartFinding]) -> PartFinding | None:
    """Whether the rack's findings are a sensor that reads unevenly over a few millimetres (None: no rack finding).

    A sensor that reads e(x) off reads the spring's force a0 e where the rack is not: the same in both directions of
    travel, the profile's bend (:attr:`FrictionProfile.bend_v`). It misreads the rack's motion there too, and a
    share of that lands in the friction at that place, as a small bind or slope. A rack's bind is friction: it flips
    with the direction, and the part of it the profile's hats cannot hold leaks into the bend, less than a step of the
    sensor does (binds and steps on the three shipped pumps: ``python docs/regenerate.py --measure
    diagnosis-uneven-shares``, docs/diagnosis.md prints them). A bend at least :data:`UNEVEN_SHARE` of the friction's
    rise is the sensor's.
    """
    if not any(f.beyond for f in rack) or profile.bend_v <= 0:
        return None
    rise_v = max(abs(profile.peak_v), abs(profile.slope_v))
    mm_per_v = abs(profile.bend_mm) / profile.bend_v
    leak_mm = UNEVEN_SHARE * rise_v * mm_per_v
    beyond = abs(profile.bend_mm) > leak_mm and abs(profile.bend_mm) > SIGNIFICANCE * profile.bend_std_mm
    return PartFinding(signature=Signature.SENSOR_UNEVEN, part=Part.SENSOR, figure=profile.bend_mm,
                       limit=leak_mm, unit="mm", at_mm=profile.bend_at_mm, std=profile.bend_std_mm, beyond=beyond)


def _mass_ratio(parameters: Mapping[str, ParameterEstimate], baseline: Baseline, tau_s: float,
                a2: tuple[float, float]) -> tuple[float, float] | None:
    """a2's share from the rack's mass (m R / K) over the baseline's: a2 less the coil's L/R times a1.

    a2 = (m R + L c) / K holds the damping c too, which a worn valve raises (+10 % on a worn valve of the default
    pump); a1 = (L k' + R c) / K, so a2 - (L / R) a1 = m R / K - L^2 k' / (R K): the damping cancels, and what is
    left scales with the reading's gain as a2 does.
    """
    a1, a2_estimate = parameters.get("a1"), parameters.get("a2")
    held = baseline.motion("a2_v_s2_per_mm")
    if a1 is None or a1.value is None or held is None or not math.isfinite(a1.value) or a2_estimate is None:
        return None
    test_v = a2_estimate.value
    base_v = held[0] - tau_s * baseline.a1_v_s_per_mm
    if test_v is None or base_v <= 0:
        return None
    return (test_v - tau_s * a1.value) / base_v, a2[1] * held[0] / base_v


def _spring_line(a0_v_per_mm: float, b_v: float, slope_per_mm: float, mid_mm: float) -> tuple[float, float]:
    """The spring's line (a0, b) with the solenoid's pull variation taken out of the fit's.

    A pull k_i (1 + s Delta) (Delta = x - x_m) divides the spring's part a0 x + b by 1 + s Delta: its value at
    mid-stroke C = a0 x_m + b stays, its slope becomes a0 - s C (the period fit's a0), and its curve is the fit's
    Delta^2 term. With s 0 the fit's a0 and b are the line's.
    """
    at_mid_v = b_v + a0_v_per_mm * mid_mm
    a0_line = a0_v_per_mm + slope_per_mm * at_mid_v
    return a0_line, at_mid_v - a0_line * mid_mm


def pump_allowance(variant: Variant, pumps: int | None) -> tuple[float, float]:
    """How far this pump's return spring may lie from the baseline's, from the type's tolerance: (a0, b) relative.

    Pumps of one type differ by their spring's rate and preload (``[rack] spring_tolerance_rel``,
    ``preload_tolerance_rel``): a rate moves a0 (by the spring's share of the net stiffness), a preload b. The
    baseline's own a0 and b are its pumps' mean: the type's figures on simulated pumps, within the tolerance over
    the square root of its pumps where it names them, and any one pump's (a whole tolerance off) where it does not
    (:attr:`~edc_bench.verdict.baseline.Baseline.pumps`, given as ``pumps``). So a test's pump lies within the
    tolerance times one plus that share.
    """
    share = 0.0 if pumps == 0 else 1.0 if not pumps else 1.0 / math.sqrt(pumps)
    rack = variant.rack
    net = rack.spring_n_per_mm - variant.coil.magnetic_stiffness_n_per_mm
    spring_a0 = rack.spring_tolerance_rel * rack.spring_n_per_mm / net if net > 0 else math.inf
    return spring_a0 * (1.0 + share), rack.preload_tolerance_rel * (1.0 + share)


def linearity_allowance_mm(variant: Variant, pumps: int | None) -> float:
    """How finely the sensor's linearity is judged on this pump type against a baseline over ``pumps`` pumps
    (:attr:`~edc_bench.verdict.baseline.Baseline.pumps`): the variant's ``sensor_linearity_mm``, or what a preload
    within the pump's allowance (:func:`pump_allowance`) moves the reading by plus the sensor's stated zero,
    whichever is larger (on a test that moved nothing else; its own spread widens it further)."""
    rack = variant.rack
    lever_mm = rack.preload_n / (rack.spring_n_per_mm - variant.coil.magnetic_stiffness_n_per_mm)
    return max(variant.diagnosis.parts.sensor_linearity_mm,
               pump_allowance(variant, pumps)[1] * lever_mm + abs(variant.sensors.lvdt.offset))


def _motion_findings(limits: PartLimits, parameters: Mapping[str, ParameterEstimate], baseline: Baseline | None,
                     rest_mm: float, tau_s: float, slope_per_mm: float = 0.0,
                     mid_mm: float = 0.0, allowance: tuple[float, float] = (0.0, 0.0),
                     zero_mm: float = 0.0) -> list[PartFinding]:
    """The sensor's gain and linearity from a2, a0 and b against the baseline's.

    A reading g times too long makes a2 and a0 (volts per millimetre read) 1/g of the baseline's and leaves b (volts)
    as it was; an offset o in the swing moves b by -a0 o and nothing else. Where the volts themselves are off (the
    rig's current sensor, the coil referred wrongly: what the rig self-check finds) all three move by one factor:
    then b is taken against a0's own ratio, which cancels it, and the gain is not judged. A spring's tolerance moves
    a0 alone (the rack's mass, a2, does not change from pump to pump).

    A solenoid whose pull varies along the stroke by s per mm (``slope_per_mm``, from the fit's Delta^2 term, per
    millimetre read) mixes the spring's line into the fit's a0 and b; they are taken apart first
    (:func:`_spring_line`). A reading g times long, o off at rest, then swings the rack about a middle
    ((g - 1) x_m + o) / g short of x_m, where the pull is kappa = 1 - s ((g - 1) x_m + o) / g of the baseline's:
    every figure is 1/kappa of what the gain alone makes it, and the slope read is s / (g kappa), so the
    baseline's s is the test's over a0's ratio.

    This pump's spring may differ from the baseline's by ``allowance`` (:func:`pump_allowance`): a0 alone by a
    rate within it (the reading's offset is then b's move over a0's, b not scaled; the gain is not judged), b by a
    preload, which reads as an offset in the swing: the linearity is judged no finer than that, nor finer than the
    reading at rest is known (``zero_mm``, the sensor's stated zero).
    """
    a2, a0, b = (_motion_ratio(parameters, baseline, key, name) for key, name in
                 (("a2_v_s2_per_mm", "a2"), ("a0_v_per_mm", "a0"), ("b_v", "b")))
    if a2 is None or a0 is None or b is None or baseline is None:
        return []
    a2 = _mass_ratio(parameters, baseline, tau_s, a2)
    if a2 is None:
        return []
    held_b, held_a0 = baseline.motion("b_v"), baseline.motion("a0_v_per_mm")
    assert held_b is not None and held_a0 is not None  # _motion_ratio found them
    base_a0, base_b = held_a0[0], held_b[0]  # the baseline's spring line
    base_slope = slope_per_mm
    if slope_per_mm != 0.0:
        test_line = _spring_line(a0[0] * base_a0, b[0] * base_b, slope_per_mm, mid_mm)  # the test's a0, b
        for _ in range(3):  # the baseline's slope is the test's over a0's ratio (a2's a misfit moves): a fixed point
            base_a0, base_b = _spring_line(held_a0[0], held_b[0], base_slope, mid_mm)
            base_slope = slope_per_mm * base_a0 / test_line[0]
        a0, b = (test_line[0] / base_a0, a0[1]), (test_line[1] / base_b, b[1])
    lever_mm = base_b / base_a0  # b over a0: how far b's move reads as an offset of the reading
    found = []
    spring_allowed, preload_allowed = allowance
    agree = abs(a2[0] - a0[0]) <= max(limits.sensor_gain_rel, SIGNIFICANCE * math.hypot(a2[1], a0[1]))
    # the reading's scale: 1/g kappa is the mean of the a2 and a0 ratios, to first order; kappa from the same g. Where
    # the spring moved a0, a2 alone would give the scale, but a2 is what a misfit moves most (a small bind near a
    # reversal: 7 %, as far as a spring moves a0): the gain is then not judged
    shrink = 2.0 / (a2[0] + a0[0])
    off_mm = rest_mm if math.isfinite(rest_mm) else 0.0
    gain = (shrink - base_slope * (mid_mm - off_mm)) / (1.0 - base_slope * mid_mm)
    kappa = 1.0 - base_slope * ((gain - 1.0) * mid_mm + off_mm) / gain
    tolerance = max(limits.sensor_gain_rel, SIGNIFICANCE * a2[1])
    b_stayed = abs(b[0] * kappa - 1.0) <= 0.5 * abs(gain - 1.0)  # a gain leaves b (volts); the volts' factor not
    gain_beyond = agree and b_stayed and abs(gain - 1.0) > tolerance
    found.append(PartFinding(signature=Signature.SENSOR_GAIN, part=Part.SENSOR, figure=gain - 1.0,
                             limit=limits.sensor_gain_rel, beyond=gain_beyond))
    if not agree and abs(a0[0] / a2[0] - 1.0) > tolerance:
        spring_limit = max(tolerance, spring_allowed + SIGNIFICANCE * math.hypot(a2[1], a0[1]))
        found.append(PartFinding(signature=Signature.SPRING_RATE, part=Part.NONE, figure=a0[0] / a2[0] - 1.0,
                                 limit=spring_limit, beyond=abs(a0[0] / a2[0] - 1.0) > spring_limit))
    if not gain_beyond and math.isfinite(rest_mm):
        # b's move beyond a0's as an offset o of the reading in the swing: b over a0 ratios g - a0 o / b (kappa
        # cancels). Whether a0 moved by a gain g within its limit, by the volts' own factor (g 1: it cancels) or by
        # the pump's spring (which moves a0 and not b: g 1 / a0's ratio, whatever a misfit did to a2, the figure it
        # moves most) one test cannot tell: the offset is the one nearest the rest reading
        scales = (1.0, gain, 1.0 / a0[0]) if agree else (1.0, 1.0 / a0[0])
        offset_mm = min(((g - b[0] / a0[0]) * lever_mm for g in scales), key=lambda o: abs(o - rest_mm))
        # a preload within the pump's allowance moves b as an offset of that many millimetres would
        limit = max(limits.sensor_linearity_mm,
                    (preload_allowed + SIGNIFICANCE * math.hypot(b[1], a0[1])) * lever_mm / a0[0] + zero_mm)
        found.append(PartFinding(signature=Signature.SENSOR_LINEARITY, part=Part.SENSOR, figure=offset_mm - rest_mm,
                                 limit=limit, unit="mm", beyond=abs(offset_mm - rest_mm) > limit))
    return found


def diagnose_parts(variant: Variant, signatures: PumpSignatures, parameters: Mapping[str, ParameterEstimate],
                   baseline: Baseline | None, features_rel: tuple[float, float] | None,
                   fit_trusted: bool = True) -> PartDiagnosis:
    """The part at fault in one test, with every signature's figure against its limit.

    Parameters
    ----------
    variant : Variant
        Its ``[diagnosis.parts]`` limits and the sensor's stated noise.
    signatures : PumpSignatures
        What the test measured of the rack and the sensor.
    parameters : mapping of str to ParameterEstimate
        The test's identified parameters, referred to the reference coil.
    baseline : Baseline or None
        The new-valve baseline the test was judged against (its af, and its a2, a0 and b where it holds them).
    features_rel : (float, float) or None
        af and a1 over the baseline's (None: no baseline to compare with).
    fit_trusted : bool, optional
        The test's fit ran its periods without the bench's own faults (no stalls, missing replies or abort): the
        figures fitted from it (the friction profile, a2, a0, b) and the reading's noise are judged only then; its
        spikes, dropouts and rest reading always.
    """
    limits = variant.diagnosis.parts
    reading = signatures.reading
    findings = _reading_findings(limits, reading, fit_trusted)
    reading_sound = not any(f.beyond for f in findings if f.signature is not Signature.SENSOR_ZERO)
    profile = signatures.friction if fit_trusted else None
    swing_mm = sum(t.amplitude_mm for t in variant.excitation.active_tones)
    solenoid_rel = math.nan if profile is None else abs(profile.gain_slope_per_mm) * swing_mm
    if profile is not None and not solenoid_rel <= PROFILE_GAIN_LIMIT_REL:
        profile = None  # a solenoid this far from linear: the friction along the stroke cannot be told from it
    af0 = baseline.af_v if baseline is not None else math.nan
    if profile is not None and reading_sound and math.isfinite(af0) and af0 > 0:
        rack = _rack_findings(limits, profile, af0)
        uneven = _uneven_finding(profile, rack)
        findings += rack if uneven is None else [uneven, *rack]
    # the motion parameters, where neither the reading nor a rack that binds (a misfit the fit spreads over every
    # parameter) biases them
    if fit_trusted and reading_sound and not any(f.beyond for f in findings):
        tau_s = variant.coil.inductance_mh * 1e-3 / variant.coil.resistance_ohm  # the reference coil's L / R
        slope = signatures.friction.gain_slope_per_mm if signatures.friction is not None else 0.0
        findings += _motion_findings(limits, parameters, baseline, reading.rest_mm, tau_s, slope,
                                     variant.rack.mid_stroke_mm,
                                     pump_allowance(variant, None if baseline is None else baseline.pumps),
                                     abs(variant.sensors.lvdt.offset))
    beyond = [f for f in findings if f.beyond and f.part in (Part.SENSOR, Part.RACK)]
    if any(f.part is Part.SENSOR for f in beyond):
        part = Part.SENSOR
    elif beyond:
        part = Part.RACK
    elif features_rel is not None and math.isfinite(features_rel[0]) \
            and features_rel[0] - 1.0 > limits.uniform_friction_rel:
        findings.append(PartFinding(signature=Signature.UNIFORM_FRICTION, part=Part.VALVE_OR_RACK,
                                    figure=features_rel[0] - 1.0, limit=limits.uniform_friction_rel, beyond=True))
        part = Part.VALVE_OR_RACK
    else:
        part = Part.NONE
    shown = signatures.friction
    summary = None if shown is None else FrictionProfileSummary(
        positions_mm=list(shown.positions_mm), friction_v=list(shown.friction_v), std_v=list(shown.std_v),
        gain_slope_per_mm=shown.gain_slope_per_mm, periods=shown.periods)
    unknown = [*NOT_IDENTIFIED, _outside_swing(summary, variant.rack.stroke_mm)]
    if math.isfinite(solenoid_rel) and solenoid_rel > PROFILE_GAIN_LIMIT_REL:
        unknown.append(f"the rack's friction along the stroke: the solenoid's pull varies about +/-{solenoid_rel:.0%} "
                       f"over the swing (judged to +/-{PROFILE_GAIN_LIMIT_REL:.0%})")
    if baseline is None or baseline.motion("a2_v_s2_per_mm") is None:
        unknown.append("the sensor's gain and linearity (the baseline holds no a2, a0 and b: calibrate the pump type "
                       "again to add them)")
    return PartDiagnosis(
        part=part, valve_judged=part not in (Part.SENSOR, Part.RACK), findings=findings, friction_profile=summary,
        reading=ReadingSummary(rest_mm=reading.rest_mm, noise_mm=reading.noise_mm,
                               expected_noise_mm=reading.expected_noise_mm, spikes=reading.spikes,
                               dropouts=reading.dropouts),
        not_identified=unknown, compared_with=None if baseline is None else baseline.summary())


def part_reasons(diagnosis: PartDiagnosis) -> list[str]:
    """Why a test whose rack or sensor is at fault does not judge the valve, one sentence a finding (the engineer's
    reasons; the technician's line is :func:`~edc_bench.records.advice.part_words`)."""
    from edc_bench.verdict.part_words import finding_words

    return [f"{finding_words(f)}; the valve's figures are biased by it, so the valve is not judged"
            for f in diagnosis.beyond]
