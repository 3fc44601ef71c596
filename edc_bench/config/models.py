"""Pump variant configuration: pydantic models, one per TOML section.

Every number carries its unit in its name. Unknown keys are rejected so that a
misspelt key never silently falls back to a default. Relations between
sections (travel limits inside the stroke, drive limit within the amplifier,
mid-stroke reachable without tripping over-current) are checked in
:class:`Variant`.
"""

from __future__ import annotations

from typing import Annotated

from pydantic import BaseModel, ConfigDict, Field, model_validator

PositiveFloat = Annotated[float, Field(gt=0, allow_inf_nan=False)]
NonNegativeFloat = Annotated[float, Field(ge=0, allow_inf_nan=False)]


class _Section(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, strict=False)


class PumpSection(_Section):
    """Identity of the pump variant."""

    name: Annotated[str, Field(min_length=1, pattern=r"^[a-z0-9][a-z0-9_.-]*$")]
    part_number: Annotated[str, Field(min_length=1)]
    description: str = ""


class RackSection(_Section):
    """Rack, spring and pump-side mechanics (paper eq. 1)."""

    stroke_mm: PositiveFloat
    mid_stroke_mm: PositiveFloat
    mass_kg: PositiveFloat
    spring_n_per_mm: PositiveFloat
    preload_n: NonNegativeFloat
    damping_n_s_per_mm: NonNegativeFloat = Field(
        description="pump-side viscous damping, excluding the valve's own"
    )


class CoilSection(_Section):
    """Solenoid coil, magnetic force and drive amplifier (paper eqs. 2-3)."""

    resistance_ohm: PositiveFloat
    inductance_mh: PositiveFloat
    force_constant_n_per_a: PositiveFloat
    magnetic_stiffness_n_per_mm: NonNegativeFloat
    amplifier_gain: PositiveFloat = 1.0
    amplifier_limit_v: PositiveFloat


class ValvePreset(_Section):
    """A named valve condition (``--valve NAME``)."""

    clearance_mm: PositiveFloat
    roughness: PositiveFloat = 1.0


class ValveSection(_Section):
    """How plunger wear maps to friction and damping (paper sec. 4).

    Coulomb friction and the valve's damping grow linearly with the clearance
    beyond a new valve's; ``roughness`` (uneven wear, the paper's valve V3)
    multiplies both. ``spread_rel`` is the log-normal spread between valves of
    the same clearance.
    """

    clearance_new_mm: PositiveFloat
    clearance_spec_mm: PositiveFloat
    coulomb_friction_new_n: PositiveFloat
    friction_gain_per_mm: NonNegativeFloat
    damping_new_n_s_per_mm: NonNegativeFloat
    damping_gain_per_mm: NonNegativeFloat
    stiction_ratio: Annotated[float, Field(ge=1.0, le=5.0, allow_inf_nan=False)] = 1.3
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

    noise_sd: NonNegativeFloat
    resolution: PositiveFloat
    offset: Annotated[float, Field(allow_inf_nan=False)] = 0.0


class SensorsSection(_Section):
    """LVDT (mm) and coil current sensor (A)."""

    lvdt: SensorModel
    current: SensorModel


class RigSection(_Section):
    """Rig firmware limits and timing (ICD v1)."""

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
        hold_v = hold_a * coil.resistance_ohm / coil.amplifier_gain
        if hold_v >= rig.drive_limit_v:
            raise ValueError(
                f"holding the rack at travel_max_mm needs {hold_v:.2f} V, at or above rig.drive_limit_v "
                f"({rig.drive_limit_v} V)"
            )
        return self
