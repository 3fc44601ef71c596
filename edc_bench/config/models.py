"""Pump variant configuration: pydantic models, one per TOML section.

Every number carries its unit in its name. Unknown keys are rejected so that a
misspelt key never silently falls back to a default. Physical values must lie
in a plausible range (each section's ``plausible`` table, with the reason in
the message): a value valid for pydantic but absurd for a pump (a 1e308 kg
rack, a 1 km stroke) is a typing or unit error, and would otherwise reach the
gain check or the simulation. Relations between sections (travel limits
inside the stroke, drive limit within the amplifier, mid-stroke reachable
without tripping over-current) are checked in :class:`Variant`.
"""

from __future__ import annotations

import enum
import re
from typing import Annotated, Any, ClassVar, Literal, NamedTuple, get_args

from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    PrivateAttr,
    ValidationInfo,
    field_validator,
    model_validator,
)

PositiveFloat = Annotated[float, Field(gt=0, allow_inf_nan=False)]
NonNegativeFloat = Annotated[float, Field(ge=0, allow_inf_nan=False)]


class Plausible(NamedTuple):
    """The range a physical value takes in any P-EDC pump and bench, generous on purpose, and why."""

    low: float
    high: float
    unit: str
    reason: str  # completes "... <low> to <high> <unit>", e.g. "a rack with its armature weighs"

    def check(self, value: float) -> None:
        """Raise ValueError (pydantic reports it against the key) if ``value`` lies outside the range."""
        if not self.low <= value <= self.high:
            raise ValueError(f"implausible: {self.reason} {self.low:g} to {self.high:g} {self.unit}; check the "
                             "value and its unit")


class _Section(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, strict=False)

    #: key -> its plausible range, checked after the key's type and sign (see :class:`Plausible`)
    plausible: ClassVar[dict[str, Plausible]] = {}

    @field_validator("*", mode="after")
    @classmethod
    def _plausible(cls, value: Any, info: ValidationInfo) -> Any:
        limits = cls.plausible.get(info.field_name or "")
        if limits is not None:
            for number in value.values() if isinstance(value, dict) else [value]:  # one gain, or one per parameter
                if isinstance(number, int | float):
                    limits.check(float(number))
        return value


class PumpSection(_Section):
    """Identity of the pump variant."""

    # at most 64 characters: the name is part of every record folder's name (255 bytes at most)
    name: Annotated[str, Field(min_length=1, max_length=64, pattern=r"^[a-z0-9][a-z0-9_.-]*$")]
    part_number: Annotated[str, Field(min_length=1)]
    description: str = ""


class RackSection(_Section):
    """Rack, spring and pump-side mechanics (paper eq. 1)."""

    plausible = {
        "stroke_mm": Plausible(1, 60, "mm", "an in-line pump's control rack travels"),
        "mid_stroke_mm": Plausible(0.5, 60, "mm", "mid-stroke of a control rack lies at"),
        "mass_kg": Plausible(0.01, 10, "kg", "a control rack with the solenoid's armature weighs"),
        "spring_n_per_mm": Plausible(0.01, 100, "N/mm", "a rack's return spring has a rate of"),
        "preload_n": Plausible(0, 500, "N", "a return spring's preload is"),
        "damping_n_s_per_mm": Plausible(0, 10, "N s/mm", "the pump side damps the rack by"),
    }

    stroke_mm: PositiveFloat
    mid_stroke_mm: PositiveFloat
    mass_kg: PositiveFloat
    spring_n_per_mm: PositiveFloat
    preload_n: NonNegativeFloat
    damping_n_s_per_mm: NonNegativeFloat = Field(
        description="pump-side viscous damping, excluding the valve's own"
    )
    spring_tolerance_rel: Annotated[float, Field(ge=0, le=0.3, allow_inf_nan=False)] = Field(
        default=0.05, description="how far one pump's return spring rate may lie from spring_n_per_mm, either way "
                                  "(relative): pumps of the type differ by it, and the part diagnosis allows it")
    preload_tolerance_rel: Annotated[float, Field(ge=0, le=0.5, allow_inf_nan=False)] = Field(
        default=0.05, description="how far one pump's return spring preload may lie from preload_n, either way "
                                  "(relative): a preload moves the spring's line as a sensor's bow does, so the "
                                  "sensor's linearity is judged no finer than this allows")


class CoilSection(_Section):
    """Solenoid coil, magnetic force and drive amplifier (paper eqs. 2-3)."""

    plausible = {
        "resistance_ohm": Plausible(0.05, 100, "ohm", "a rack solenoid's coil measures"),
        "resistance_min_ohm": Plausible(0.05, 100, "ohm", "a rack solenoid's coil measures"),
        "resistance_max_ohm": Plausible(0.05, 100, "ohm", "a rack solenoid's coil measures"),
        "inductance_mh": Plausible(0.01, 1000, "mH", "a rack solenoid's inductance is"),
        "force_constant_n_per_a": Plausible(0.01, 500, "N/A", "a rack solenoid pulls with"),
        "magnetic_stiffness_n_per_mm": Plausible(0, 100, "N/mm", "a solenoid's magnetic stiffness is"),
        "amplifier_gain": Plausible(0.01, 100, "", "a drive amplifier's gain is"),
        "amplifier_limit_v": Plausible(0.5, 100, "V", "a bench amplifier (12, 24 or 48 V supplies) drives at most"),
    }

    resistance_ohm: PositiveFloat = Field(description="nominal coil resistance at 20 degC (the reference coil)")
    inductance_mh: PositiveFloat
    force_constant_n_per_a: PositiveFloat
    magnetic_stiffness_n_per_mm: NonNegativeFloat
    amplifier_gain: PositiveFloat = 1.0
    amplifier_limit_v: PositiveFloat
    resistance_min_ohm: PositiveFloat | None = Field(
        default=None, description="lowest coil resistance at 20 degC the manufacturer accepts (none: not judged)")
    resistance_max_ohm: PositiveFloat | None = Field(
        default=None, description="highest coil resistance at 20 degC the manufacturer accepts (none: not judged)")
    temperature_coefficient_per_k: Annotated[float, Field(ge=0, le=0.01, allow_inf_nan=False)] = Field(
        default=0.00393, description="relative change of the coil's resistance per kelvin (copper: 0.00393)")
    thermal_capacity_j_per_k: Annotated[float, Field(gt=0, le=1e5, allow_inf_nan=False)] = Field(
        default=40.0, description="heat that warms the coil by 1 K (simulated rig)")
    thermal_resistance_k_per_w: Annotated[float, Field(gt=0, le=1e3, allow_inf_nan=False)] = Field(
        default=3.0, description="coil temperature rise per watt dissipated, in steady state (simulated rig)")
    force_constant_variation_per_mm: Annotated[float, Field(ge=-0.1, le=0.1, allow_inf_nan=False)] = Field(
        default=0.0, description="relative change of force_constant_n_per_a per mm of rack travel from mid-stroke "
        "(simulated rig: a real proportional solenoid's pull varies with position; 0: constant)")

    @model_validator(mode="after")
    def _spec(self) -> CoilSection:
        low = self.resistance_min_ohm if self.resistance_min_ohm is not None else 0.0
        high = self.resistance_max_ohm if self.resistance_max_ohm is not None else float("inf")
        if not low <= self.resistance_ohm <= high:
            raise ValueError(f"coil.resistance_ohm ({self.resistance_ohm}) must lie within the coil spec "
                             f"[resistance_min_ohm, resistance_max_ohm] = [{self.resistance_min_ohm}, "
                             f"{self.resistance_max_ohm}]")
        return self


class ValvePreset(_Section):
    """A named valve condition (``--valve NAME``)."""

    clearance_mm: PositiveFloat
    roughness: PositiveFloat = 1.0

    plausible = {
        "clearance_mm": Plausible(0.001, 2, "mm", "a plunger clearance, new to scrap, is"),
        "roughness": Plausible(0.1, 5, "", "uneven wear multiplies friction and damping by"),
    }


class ValveSection(_Section):
    """How plunger wear maps to friction and damping (paper sec. 4).

    Coulomb friction and the valve's damping grow linearly with the clearance
    beyond a new valve's; ``roughness`` (uneven wear, the paper's valve V3)
    multiplies both. ``spread_rel`` is the log-normal spread between valves of
    the same clearance.
    """

    plausible = {
        "clearance_new_mm": Plausible(0.001, 2, "mm", "a plunger clearance, new to scrap, is"),
        "clearance_spec_mm": Plausible(0.001, 2, "mm", "a plunger clearance, new to scrap, is"),
        "coulomb_friction_new_n": Plausible(0.001, 100, "N", "a new valve's Coulomb friction is"),
        "friction_gain_per_mm": Plausible(0, 1000, "1/mm", "friction grows with clearance by"),
        "damping_new_n_s_per_mm": Plausible(0, 10, "N s/mm", "a new valve damps the rack by"),
        "damping_gain_per_mm": Plausible(0, 1000, "1/mm", "damping grows with clearance by"),
    }

    clearance_new_mm: PositiveFloat
    clearance_spec_mm: PositiveFloat
    coulomb_friction_new_n: PositiveFloat
    friction_gain_per_mm: NonNegativeFloat
    damping_new_n_s_per_mm: NonNegativeFloat
    damping_gain_per_mm: NonNegativeFloat
    stiction_ratio: Annotated[float, Field(ge=1.0, le=5.0, allow_inf_nan=False)] = 1.3
    stribeck_velocity_mm_s: Annotated[float, Field(ge=0, le=1000, allow_inf_nan=False)] = Field(
        default=0.0, description="Stribeck speed (simulated rig): sliding friction falls from the breakaway force "
        "to Coulomb friction as exp(-(v/v_s)^2); 0: it falls at once")
    spread_rel: Annotated[float, Field(ge=0.0, le=0.5, allow_inf_nan=False)] = 0.08
    presets: dict[str, ValvePreset]

    @model_validator(mode="after")
    def _presets_needed(self) -> ValveSection:
        missing = {"new", "worn", "faulty"} - set(self.presets)
        if missing:
            raise ValueError(f"presets must define new, worn and faulty; missing: {', '.join(sorted(missing))}")
        if self.clearance_spec_mm < self.clearance_new_mm:
            raise ValueError(
                f"clearance_spec_mm ({self.clearance_spec_mm}) must not be below clearance_new_mm "
                f"({self.clearance_new_mm})"
            )
        return self


class SensorModel(_Section):
    """One sensor: additive offset and Gaussian noise, then quantisation."""

    plausible = {
        "noise_sd": Plausible(0, 1, "mm or A", "a rack position or coil current sensor's noise is"),
        "resolution": Plausible(1e-6, 1, "mm or A", "a rack position or coil current sensor resolves"),
        "offset": Plausible(-5, 5, "mm or A", "a rack position or coil current sensor's offset is"),
    }

    noise_sd: NonNegativeFloat
    resolution: PositiveFloat
    offset: Annotated[float, Field(allow_inf_nan=False)] = 0.0


class SensorsSection(_Section):
    """LVDT (mm) and coil current sensor (A)."""

    lvdt: SensorModel
    current: SensorModel


class RigSection(_Section):
    """Rig firmware limits and timing (ICD v1)."""

    plausible = {
        "drive_limit_v": Plausible(0.5, 100, "V", "a rig drives its coil with at most"),
        "over_current_a": Plausible(0.1, 100, "A", "a rig trips over-current at"),
        "travel_max_mm": Plausible(0.5, 60, "mm", "a rack's upper travel limit is"),
        "supply_voltage_v": Plausible(1, 100, "V", "a bench supply gives"),
        "supply_min_v": Plausible(0, 100, "V", "a bench supply's lowest allowed voltage is"),
        "boot_ms": Plausible(0, 60000, "ms", "a rig boots in"),
    }

    drive_limit_v: PositiveFloat
    over_current_a: PositiveFloat
    travel_min_mm: Annotated[float, Field(ge=-5.0, allow_inf_nan=False)] = Field(
        description="below the 0 mm rest stop by a margin, so sensor noise at rest does not trip"
    )
    travel_max_mm: PositiveFloat
    supply_voltage_v: PositiveFloat = 24.0
    supply_min_v: NonNegativeFloat = 18.0
    watchdog_ms: Annotated[float, Field(gt=0, le=1000, allow_inf_nan=False)] = 20.0
    heartbeat_period_ms: Annotated[float, Field(gt=0, le=10000, allow_inf_nan=False)] = 100.0
    boot_ms: NonNegativeFloat = 200.0


class ToneSection(_Section):
    """One sine of the excitation."""

    plausible = {"amplitude_mm": Plausible(0.001, 30, "mm", "a tone moves the rack by")}

    frequency_hz: Annotated[float, Field(gt=0, le=50, allow_inf_nan=False)]
    amplitude_mm: PositiveFloat
    phase_deg: Annotated[float, Field(ge=-360, le=360, allow_inf_nan=False)] = 0.0


class ExcitationSection(_Section):
    """The reference the rack follows during a test (about mid-stroke).

    ``shape = "sine"`` uses only the first tone (the paper's 0.5 Hz sine; it
    cannot separate a3 from a1, see docs/method.md section 10 d). ``"multisine"`` sums all tones.
    """

    plausible = {
        "move_s": Plausible(0.01, 10, "s", "moving the rack to mid-stroke takes"),
        "fade_s": Plausible(0.01, 10, "s", "fading the excitation in takes"),
        "duration_s": Plausible(1, 600, "s", "a bench test lasts"),
    }

    shape: Literal["sine", "multisine"] = "multisine"
    tones: Annotated[list[ToneSection], Field(min_length=1, max_length=8)]
    move_s: PositiveFloat = 1.0
    fade_s: PositiveFloat = 1.0
    duration_s: PositiveFloat = 30.0

    @property
    def active_tones(self) -> list[ToneSection]:
        """The tones the shape uses."""
        return self.tones[:1] if self.shape == "sine" else self.tones

    @model_validator(mode="after")
    def _long_enough(self) -> ExcitationSection:
        if self.duration_s <= self.move_s + self.fade_s:
            raise ValueError(
                f"duration_s ({self.duration_s}) must exceed move_s + fade_s ({self.move_s + self.fade_s})"
            )
        return self


class ControllerSection(_Section):
    """Loop rate and PID feedback gains, checked against the nominal plant."""

    plausible = {
        "period_s": Plausible(1e-4, 0.01, "s", "the bench loop runs at 100 Hz to 10 kHz, a period of"),
        "kp_v_per_mm": Plausible(0, 100, "V/mm", "a rack position loop's proportional gain is"),
        "ki_v_per_mm_s": Plausible(0, 10000, "V/(mm s)", "a rack position loop's integral gain is"),
        "kd_v_s_per_mm": Plausible(0, 10, "V s/mm", "a rack position loop's derivative gain is"),
        "derivative_filter_hz": Plausible(0.1, 5000, "Hz", "the derivative filter's corner lies at"),
        "min_gain_margin_db": Plausible(0, 60, "dB", "a gain margin asked for is"),
    }

    period_s: PositiveFloat = 0.001
    kp_v_per_mm: NonNegativeFloat
    ki_v_per_mm_s: NonNegativeFloat
    kd_v_s_per_mm: NonNegativeFloat
    derivative_filter_hz: PositiveFloat = 100.0
    min_gain_margin_db: NonNegativeFloat = 6.0
    min_phase_margin_deg: Annotated[float, Field(ge=0, le=90, allow_inf_nan=False)] = 30.0


#: The feedforward's parameters, in the order of its regressor [r''', r'', r', r, 1, sgn r'].
ParameterName = Literal["a3", "a2", "a1", "a0", "b", "af"]
PARAMETER_NAMES: tuple[str, ...] = get_args(ParameterName)


class EstimatorKind(enum.StrEnum):
    """The online estimator's law (``[estimator] kind``): recursive least squares, or a gradient law."""

    RLS = "rls"
    GRADIENT = "gradient"


class EstimatorSection(_Section):
    """Online estimation of the feedforward parameters.

    Parameters not listed in ``estimate`` stay at their nominal value (from
    the variant's physics); list only what the excitation makes identifiable.
    """

    plausible = {
        "initial_std_rel": Plausible(1e-6, 100, "", "the prior spread, relative to the nominal values, is"),
        "gradient_gains_per_s": Plausible(1e-6, 1e5, "1/s", "a gradient law's gain is"),
    }

    kind: EstimatorKind = EstimatorKind.RLS
    estimate: Annotated[list[ParameterName], Field(min_length=1)] = [
        "a2", "a1", "a0", "b", "af",
    ]
    forgetting_factor: Annotated[float, Field(gt=0.99, le=1.0, allow_inf_nan=False)] = 0.9995
    initial_std_rel: PositiveFloat = 1.0
    gradient_gains_per_s: dict[ParameterName, PositiveFloat] | PositiveFloat = Field(
        default=40.0, description="gradient law: one gain for all normalised parameters, or one per parameter",
    )
    reversal_exclusion: Annotated[float, Field(ge=0, lt=1, allow_inf_nan=False)] = Field(
        default=0.3, description="no update while |r'| is below this fraction of its peak (stick windows)",
    )

    @model_validator(mode="after")
    def _af_and_a1(self) -> EstimatorSection:
        missing = {"a1", "af"} - set(self.estimate)
        if missing:
            raise ValueError(f"estimate must include a1 and af (the diagnosis features); missing {sorted(missing)}")
        if len(set(self.estimate)) != len(self.estimate):
            raise ValueError("estimate lists a parameter twice")
        if isinstance(self.gradient_gains_per_s, dict):
            missing_gains = set(self.estimate) - set(self.gradient_gains_per_s)
            if missing_gains:
                raise ValueError(f"gradient_gains_per_s needs a gain for {sorted(missing_gains)}")
        return self


class AcceptanceSection(_Section):
    """When a test counts as trustworthy (else INVALID)."""

    plausible = {
        "convergence_window_s": Plausible(0.1, 600, "s", "the window the online estimates' settle times look at is"),
        "max_condition_number": Plausible(1.01, 1e12, "", "a usable regressor's condition number is at most"),
        "max_tracking_error_mm": Plausible(0.01, 60, "mm", "the rack may stray from its reference by"),
        "ready_timeout_s": Plausible(0.1, 600, "s", "a rig reports READY within"),
    }

    settle_band_rel: Annotated[float, Field(gt=0, lt=1, allow_inf_nan=False)] = Field(
        default=0.02, description="settled: af and a1 over the first half of the excitation periods and over the "
        "second half agree within this (relative), or, from 8 periods on, within what their period-to-period noise "
        "explains")
    min_periods: Annotated[int, Field(ge=2, le=100)] = Field(
        default=3, description="whole excitation periods (after the first, which learns) a verdict needs at least")
    max_residual_ratio: Annotated[float, Field(gt=1, le=1000, allow_inf_nan=False)] = Field(
        default=5.0, description="the model does not fit when what it leaves unexplained of the smoothed drive the "
        "same way in every excitation period exceeds this multiple of the noise the position sensor leaves in it "
        "(docs/method.md, section 15, prints what fitting pumps reach, through a USB adapter too)")
    max_gain_variation_rel: Annotated[float, Field(gt=0, le=1, allow_inf_nan=False)] = Field(
        default=0.25, description="the model does not fit when the solenoid's force constant varies more than this "
        "(+/-, relative) over the excitation's swing: its first-order correction no longer holds")
    verdict_confidence: Annotated[float, Field(ge=0.5, lt=1, allow_inf_nan=False)] = Field(
        default=0.99, description="a test stops early when af and a1 within this confidence interval cannot change "
        "the verdict")
    convergence_window_s: PositiveFloat = 5.0
    max_condition_number: Annotated[float, Field(gt=1, allow_inf_nan=False)] = 1e4
    max_missed_replies_in_row: Annotated[int, Field(ge=1, le=100)] = 5
    max_overrun_fraction: Annotated[float, Field(ge=0, le=1, allow_inf_nan=False)] = Field(
        default=0.01, description="share of ticks that may overrun or be lost to host stalls before a test whose fit "
                                 "is not trusted (or that was cut short) is INVALID for its timing, the PC named: "
                                 "the fit leaves out the rows a stall touched, and what remains decides",
    )
    max_missed_reply_fraction: Annotated[float, Field(ge=0, le=1, allow_inf_nan=False)] = 0.01
    max_reply_age_ms: Annotated[float, Field(gt=0, le=50, allow_inf_nan=False)] = Field(
        default=4.0, description="a reply older than this (from its command's tick) is never used; the gain check "
        "takes it as the loop's worst transport delay. 4 ms: a USB full-speed adapter (1.5-3.5 ms round trip); "
        "2 ms suffices for PCI and socketcan adapters and allows faster gains",
    )
    max_frames_per_tick: Annotated[int, Field(ge=4, le=10000)] = Field(
        default=64, description="frames read in one tick before the bus counts as flooded and the test ends",
    )
    heartbeat_timeout_periods: Annotated[float, Field(gt=1, le=20, allow_inf_nan=False)] = 3.0
    max_tracking_error_mm: PositiveFloat = Field(
        default=2.0, description="abort if the rack stays this far from its reference (a stuck sensor or rack)"
    )
    tracking_error_ticks: Annotated[int, Field(ge=1, le=10000)] = Field(
        default=100, description="ticks in a row beyond max_tracking_error_mm that end the test: twice a sticky "
        "valve's longest stick-slip (50 ms, a faulty valve on a pump the model fits badly), and short enough that a "
        "stuck sensor is caught before the PID winds the coil up to the rig's over-current trip",
    )
    ready_timeout_s: PositiveFloat = 3.0


VerdictName = Literal["PASS", "MARGINAL", "FAIL", "INVALID"]


class RetestSection(_Section):
    """What the bench does after a MARGINAL: it tests the valve again at once, and the two tests decide together.

    ``decide`` maps the retest's verdict to what the pair decides: PASS (refit the valve), FAIL (replace it) or
    INVALID (the retest was not judged: check what it names, then test again). A second MARGINAL must decide
    PASS or FAIL: a valve is never left near the limit.
    """

    after_marginal: bool = Field(
        default=True, description="test a MARGINAL valve again at once (false: the technician decides)")
    decide: dict[VerdictName, Literal["PASS", "FAIL", "INVALID"]] = Field(
        default={"PASS": "PASS", "MARGINAL": "FAIL", "FAIL": "FAIL", "INVALID": "INVALID"},
        description="the retest's verdict -> what the two tests decide (default: a FAIL or a second MARGINAL "
                    "replaces the valve, a PASS refits it)")

    @model_validator(mode="after")
    def _whole(self) -> RetestSection:
        missing = [v for v in ("PASS", "MARGINAL", "FAIL", "INVALID") if v not in self.decide]
        if missing:
            raise ValueError(f"decide needs what every retest verdict decides; missing {', '.join(missing)} "
                             '(e.g. MARGINAL = "FAIL")')
        if self.decide["MARGINAL"] == "INVALID":
            raise ValueError('decide.MARGINAL must be "PASS" or "FAIL": two judged tests decide the valve')
        if self.decide["INVALID"] != "INVALID":
            raise ValueError('decide.INVALID must be "INVALID": a retest that was not judged decides nothing')
        return self


class PopulationSection(_Section):
    """How the simulated population of used valves is drawn."""

    plausible = {
        "clearance_min_mm": Plausible(0.001, 2, "mm", "a plunger clearance, new to scrap, is"),
        "clearance_max_mm": Plausible(0.001, 2, "mm", "a plunger clearance, new to scrap, is"),
    }

    clearance_min_mm: PositiveFloat
    clearance_max_mm: PositiveFloat
    rough_fraction: Annotated[float, Field(ge=0, le=1, allow_inf_nan=False)] = 0.2
    roughness_max: Annotated[float, Field(ge=1, le=5, allow_inf_nan=False)] = 2.2
    coil_temp_min_c: Annotated[float, Field(ge=-40, le=150, allow_inf_nan=False)] = Field(
        default=20.0, description="coldest coil at the start of a simulated test")
    coil_temp_max_c: Annotated[float, Field(ge=-40, le=150, allow_inf_nan=False)] = Field(
        default=60.0, description="warmest coil at the start of a simulated test (a coil warm from earlier tests)")

    @model_validator(mode="after")
    def _range(self) -> PopulationSection:
        if self.clearance_max_mm <= self.clearance_min_mm:
            raise ValueError("clearance_max_mm must exceed clearance_min_mm")
        if self.coil_temp_max_c < self.coil_temp_min_c:
            raise ValueError("coil_temp_max_c must not be below coil_temp_min_c")
        return self


class PartLimits(_Section):
    """From what size a fault of the pump's control rack or its rack-travel sensor is named (docs/diagnosis.md,
    "Which part is at fault", reasons for each). Below them the part is reported as sound.

    The rack's figures are relative to the new-valve baseline's friction af0: a rack whose friction rises by
    ``rack_bind_rel`` af0 at one place, or by ``rack_slope_rel`` af0 across the swing, binds or drags.
    """

    plausible = {
        "rack_bind_rel": Plausible(0.01, 10, "", "a limit on the rack's friction rising at one place (a share of a new "
                                                 "valve's friction) lies within"),
        "rack_slope_rel": Plausible(0.01, 10, "", "a limit on the rack's friction changing along the swing (a share of "
                                                  "a new valve's friction) lies within"),
        "uniform_friction_rel": Plausible(0.01, 10, "", "a limit on friction above a new valve's along the whole "
                                                        "stroke (a share) lies within"),
        "sensor_gain_rel": Plausible(0.001, 0.5, "", "a limit on a rack-travel sensor's scale error lies within"),
        "sensor_offset_mm": Plausible(0.001, 5, "mm", "a limit on a rack-travel sensor's zero shift lies within"),
        "sensor_linearity_mm": Plausible(0.001, 5, "mm", "a limit on a rack-travel sensor's bow lies within"),
        "sensor_noise_ratio": Plausible(1.1, 100, "", "a limit on a rack-travel sensor's noise over its stated noise "
                                                      "lies within"),
    }

    rack_bind_rel: PositiveFloat = 0.15
    rack_slope_rel: PositiveFloat = 0.15
    uniform_friction_rel: PositiveFloat = 0.25
    sensor_gain_rel: PositiveFloat = 0.03
    sensor_offset_mm: PositiveFloat = 0.1
    sensor_linearity_mm: PositiveFloat = 0.1
    sensor_noise_ratio: PositiveFloat = 3.0
    sensor_spikes: int = Field(2, ge=1, description="spikes in one test from which the sensor is named")
    sensor_dropouts: int = Field(1, ge=1, description="dropouts in one test from which the sensor's contact is named")


class DiagnosisSection(_Section):
    """The physical limit that makes a valve faulty, and the population.

    A valve is faulty when the force it opposes to the rack at a typical
    governor speed, Coulomb friction plus damping, exceeds the limit:
    ``F_c + c * resistance_speed_mm_s > resistance_limit_n``. The label of a
    simulated valve comes from this physics, never from identified values.
    """

    plausible = {
        "resistance_speed_mm_s": Plausible(0.1, 10000, "mm/s", "a governor moves the rack at"),
        "resistance_limit_n": Plausible(0.001, 1000, "N", "a valve's resisting force limit is"),
    }

    resistance_speed_mm_s: PositiveFloat
    resistance_limit_n: PositiveFloat
    population: PopulationSection
    parts: PartLimits = PartLimits()
    model: str | None = Field(
        default=None,
        description="the classifier this pump's valves are judged by, a file name (built with 'edc-bench train "
                    "--variants NAME --own'), looked up in the station's models folder, then the package's; none: "
                    "the station's model (adopted, else the shipped network). For a pump whose resisting force "
                    "splits between friction and damping unlike the shipped network's pumps: one boundary in "
                    "(af/af0, a1/a1_0) does not serve both (docs/diagnosis.md)")

    @field_validator("model")
    @classmethod
    def _model_file_name(cls, value: str | None) -> str | None:
        if value is not None and not re.fullmatch(r"[A-Za-z0-9][A-Za-z0-9._-]{0,115}\.onnx", value):
            raise ValueError("give the model's file name alone (letters, digits, '.', '_', '-', ending in .onnx, "
                             "as 'edc-bench train --variants NAME --own' writes valve_mlp-NAME.onnx), not a path")
        return value


class SelfcheckSection(_Section):
    """The rig self-check with a reference valve (``edc-bench rig-selfcheck``, docs/faults.md).

    How far each figure of the reference valve and the rig at rest may move from its registration before the
    self-check is NO-GO, and how often a station must run it. The tolerances come from the spread of each
    figure over repeated runs of the simulated rig with different noise (docs/faults.md prints it), with room
    for a real rig's temperature and handling, and each below the drift it must catch (an LVDT's zero moved
    0.05 mm, a current sensor's gain 3 %).
    """

    every_tests: Annotated[int, Field(ge=1, le=100000)] | None = Field(
        default=None, description="a self-check at least every this many tests at a station (none: no limit)")
    every_hours: Annotated[float, Field(gt=0, le=8760, allow_inf_nan=False)] | None = Field(
        default=None, description="a self-check at least every this many hours at a station (none: no limit)")
    lvdt_zero_mm: Annotated[float, Field(gt=0, le=1, allow_inf_nan=False)] = Field(
        default=0.02, description="how far the rack position at rest may move (mm)")
    current_zero_a: Annotated[float, Field(gt=0, le=1, allow_inf_nan=False)] = Field(
        default=0.01, description="how far the coil current at rest may move (A)")
    coil_r20_rel: Annotated[float, Field(gt=0, le=0.5, allow_inf_nan=False)] = Field(
        default=0.015, description="how far the coil resistance measured may move (relative)")
    a0_rel: Annotated[float, Field(gt=0, le=0.5, allow_inf_nan=False)] = Field(
        default=0.015, description="how far the spring rate a0 may move (relative)")
    af_rel: Annotated[float, Field(gt=0, le=0.5, allow_inf_nan=False)] = Field(
        default=0.02, description="how far the reference valve's af may move (relative)")
    a1_rel: Annotated[float, Field(gt=0, le=0.5, allow_inf_nan=False)] = Field(
        default=0.02, description="how far the reference valve's a1 may move (relative)")


class Variant(_Section):
    """A pump variant: everything the bench and the simulated rig need.

    Load it with :func:`edc_bench.config.load_variant`.
    """

    pump: PumpSection
    rack: RackSection
    coil: CoilSection
    valve: ValveSection
    sensors: SensorsSection
    rig: RigSection
    excitation: ExcitationSection
    controller: ControllerSection
    estimator: EstimatorSection = EstimatorSection()
    acceptance: AcceptanceSection = AcceptanceSection()
    retest: RetestSection = RetestSection()
    diagnosis: DiagnosisSection
    selfcheck: SelfcheckSection = SelfcheckSection()
    _source_file: str | None = PrivateAttr(default=None)

    @property
    def source_file(self) -> str | None:
        """The file the variant was loaded from (None if it was built in memory)."""
        return self._source_file

    @property
    def name(self) -> str:
        """The variant's name."""
        return self.pump.name

    @property
    def net_stiffness_n_per_mm(self) -> float:
        """Spring stiffness less the magnet's negative stiffness (k' = k - k_x)."""
        return self.rack.spring_n_per_mm - self.coil.magnetic_stiffness_n_per_mm

    @model_validator(mode="after")
    def _relations(self) -> Variant:
        rack, coil, rig = self.rack, self.coil, self.rig
        if not 0 < rack.mid_stroke_mm < rack.stroke_mm:
            raise ValueError(
                f"rack.mid_stroke_mm ({rack.mid_stroke_mm}) must lie inside the stroke (0, {rack.stroke_mm})"
            )
        if not rig.travel_min_mm < rack.mid_stroke_mm < rig.travel_max_mm <= rack.stroke_mm:
            raise ValueError(
                "rig travel limits must satisfy travel_min_mm < rack.mid_stroke_mm < travel_max_mm "
                f"<= rack.stroke_mm; got {rig.travel_min_mm} < {rack.mid_stroke_mm} < {rig.travel_max_mm} "
                f"<= {rack.stroke_mm}"
            )
        if self.net_stiffness_n_per_mm <= 0:
            raise ValueError(
                f"coil.magnetic_stiffness_n_per_mm ({coil.magnetic_stiffness_n_per_mm}) must be below "
                f"rack.spring_n_per_mm ({rack.spring_n_per_mm}), or the rack has no stable rest position"
            )
        if rig.drive_limit_v > coil.amplifier_limit_v:
            raise ValueError(
                f"rig.drive_limit_v ({rig.drive_limit_v}) must not exceed coil.amplifier_limit_v "
                f"({coil.amplifier_limit_v})"
            )
        if rig.supply_min_v > rig.supply_voltage_v:
            raise ValueError(
                f"rig.supply_min_v ({rig.supply_min_v}) must not exceed rig.supply_voltage_v ({rig.supply_voltage_v})"
            )
        # Holding the rack at the top of its travel must not trip over-current.
        hold_a = (self.net_stiffness_n_per_mm * rig.travel_max_mm + rack.preload_n) / coil.force_constant_n_per_a
        if hold_a >= rig.over_current_a:
            raise ValueError(
                f"holding the rack at travel_max_mm needs {hold_a:.2f} A, at or above rig.over_current_a "
                f"({rig.over_current_a} A): raise over_current_a or lower travel_max_mm"
            )
        excitation = self.excitation
        swing_mm = sum(t.amplitude_mm for t in excitation.active_tones)
        if not rig.travel_min_mm < rack.mid_stroke_mm - swing_mm < rack.mid_stroke_mm + swing_mm < rig.travel_max_mm:
            raise ValueError(
                f"the excitation swings {swing_mm:g} mm about mid-stroke ({rack.mid_stroke_mm} mm), beyond the "
                f"travel limits [{rig.travel_min_mm}, {rig.travel_max_mm}]: lower the tone amplitudes"
            )
        shortest_s = excitation.move_s + excitation.fade_s + self.acceptance.convergence_window_s
        if excitation.duration_s <= shortest_s:
            raise ValueError(
                f"excitation.duration_s ({excitation.duration_s:g} s) is too short: the move ({excitation.move_s:g} s),"
                f" the fade-in ({excitation.fade_s:g} s) and the convergence window "
                f"({self.acceptance.convergence_window_s:g} s) need more than {shortest_s:g} s"
            )
        nyquist_hz = 0.5 / self.controller.period_s
        fastest = max(t.frequency_hz for t in excitation.active_tones)
        if fastest > nyquist_hz / 10:
            raise ValueError(
                f"excitation tone at {fastest} Hz is too fast for a {self.controller.period_s * 1e3:g} ms period: "
                f"keep tones below {nyquist_hz / 10:g} Hz"
            )
        period_ms = self.controller.period_s * 1e3
        if rig.watchdog_ms <= 2 * period_ms:  # a command each tick, and one late tick, must not trip it
            raise ValueError(
                f"rig.watchdog_ms ({rig.watchdog_ms:g} ms) does not outlast two ticks of the loop "
                f"(controller.period_s {period_ms:g} ms): the rig would go safe between commands; give more than "
                f"{2 * period_ms:g} ms (the ICD's default is 20 ms)"
            )
        reach_mm = max(rack.mid_stroke_mm, rack.stroke_mm - rack.mid_stroke_mm)
        if abs(coil.force_constant_variation_per_mm) * reach_mm >= 0.9:
            raise ValueError(
                f"coil.force_constant_variation_per_mm ({coil.force_constant_variation_per_mm:g}) changes the force "
                f"constant by {abs(coil.force_constant_variation_per_mm) * reach_mm:.0%} at the end of the stroke: "
                "keep it within +/-90 % over the stroke"
            )
        hold_v = hold_a * coil.resistance_ohm / coil.amplifier_gain
        if hold_v >= rig.drive_limit_v:
            raise ValueError(
                f"holding the rack at travel_max_mm needs {hold_v:.2f} V, at or above rig.drive_limit_v "
                f"({rig.drive_limit_v} V)"
            )
        return self
