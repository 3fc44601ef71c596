"""Valves described physically, and the plant they make in a pump.

A valve is its plunger clearance (wear) and surface roughness, plus the
valve-to-valve spread of its friction and damping. With a pump variant this
gives the plant's physical parameters (:func:`plant_parameters`); the
nominal new valve gives the plant the controller assumes
(:func:`nominal_plant`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from edc_bench.config.models import Variant
from edc_bench.errors import ConfigError
from edc_bench.physics.coil import resistance_at_ohm
from edc_bench.physics.parameters import PlantParameters


@dataclass(frozen=True)
class ValveSpec:
    """One solenoid valve, physically.

    Attributes
    ----------
    clearance_mm : float
        Plunger-to-sleeve clearance; grows with wear.
    roughness : float
        Multiplier for uneven wear (1 for an evenly worn valve).
    friction_scale, damping_scale : float
        This valve's deviation from the variant's wear model (spread between
        valves); 1 for a nominal valve.
    label : str
        How the valve was named (preset name or spec text), for records.
    coil_ohm : float or None
        The coil's resistance at 20 degC; None: the variant's nominal.
    coil_temp_c : float or None
        The coil's temperature when the test starts; None: the station's ambient (20 degC).
    """

    clearance_mm: float
    roughness: float = 1.0
    friction_scale: float = 1.0
    damping_scale: float = 1.0
    label: str = ""
    coil_ohm: float | None = None
    coil_temp_c: float | None = None


_SPEC_KEYS = {
    "clearance": "clearance_mm",
    "clearance_mm": "clearance_mm",
    "roughness": "roughness",
    "friction_scale": "friction_scale",
    "damping_scale": "damping_scale",
    "coil_ohm": "coil_ohm",
    "coil_temp_c": "coil_temp_c",
}
#: The simulated station's ambient: a coil that has rested starts a test at this temperature.
AMBIENT_C = 20.0


def parse_valve_spec(text: str, variant: Variant) -> ValveSpec:
    """Parse ``--valve``: a preset name or ``key=value`` pairs.

    Parameters
    ----------
    text : str
        ``new``, ``worn``, ``faulty`` (or another preset of the variant), or
        comma-separated physical values, e.g. ``clearance=0.22,roughness=1.5``
        (keys: clearance[_mm], roughness, friction_scale, damping_scale,
        coil_ohm (at 20 degC), coil_temp_c (at the start)). A preset may be
        refined: ``worn,roughness=1.2`` or ``new,coil_ohm=0.9,coil_temp_c=60``.
    variant : Variant
        Supplies the presets.

    Returns
    -------
    ValveSpec

    Raises
    ------
    ConfigError
        For an unknown preset or key, or a value that is not a positive number.
    """
    presets = variant.valve.presets
    fields: dict[str, float] = {}
    given: set[str] = set()
    for part in (p.strip() for p in text.split(",")):
        if not part:
            continue
        if "=" not in part:
            if part not in presets:
                raise ConfigError(
                    f"--valve {text!r}: unknown valve {part!r}; use one of {', '.join(sorted(presets))} "
                    "or physical values such as clearance=0.22,roughness=1.5"
                )
            fields.update(clearance_mm=presets[part].clearance_mm, roughness=presets[part].roughness)
            continue
        key, _, raw = (s.strip() for s in part.partition("="))
        if key not in _SPEC_KEYS:
            raise ConfigError(f"--valve {text!r}: unknown key {key!r}; expected one of {', '.join(sorted(_SPEC_KEYS))}")
        if key in given:
            raise ConfigError(f"--valve {text!r}: {key} is given twice; give each value once")
        given.add(key)
        try:
            value = float(raw)
        except ValueError:
            raise ConfigError(f"--valve {text!r}: {key} = {raw!r} is not a number") from None
        if key == "coil_temp_c":
            if not -40.0 <= value <= 150.0:
                raise ConfigError(f"--valve {text!r}: coil_temp_c = {raw!r} is not a plausible coil temperature "
                                  "(-40 to 150 degC)")
        elif not math.isfinite(value) or value <= 0:
            raise ConfigError(f"--valve {text!r}: {key} = {raw!r} must be a positive number")
        elif key == "coil_ohm" and value > 100.0:
            raise ConfigError(f"--valve {text!r}: coil_ohm = {raw!r} is not a plausible solenoid coil (ohm at "
                              "20 degC, below 100)")
        fields[_SPEC_KEYS[key]] = value
    if "clearance_mm" not in fields:
        raise ConfigError(f"--valve {text!r}: give a preset ({', '.join(sorted(presets))}) or clearance=MM")
    if fields["clearance_mm"] > 2.0:
        raise ConfigError(f"--valve {text!r}: clearance {fields['clearance_mm']} mm is not plausible (expected < 2 mm)")
    return ValveSpec(label=text, **fields)


def sample_valve(variant: Variant, clearance_mm: float, rng: np.random.Generator, roughness: float = 1.0,
                 label: str = "") -> ValveSpec:
    """A valve of given clearance with the variant's spread between valves.

    Parameters
    ----------
    variant : Variant
        Supplies ``valve.spread_rel`` (log-normal sigma).
    clearance_mm : float
        Plunger clearance.
    rng : numpy.random.Generator
        Source of the spread; same seed, same valve.
    roughness : float, optional
        Uneven-wear multiplier.
    label : str, optional
        Name for records.
    """
    sigma = variant.valve.spread_rel
    friction_scale, damping_scale = np.exp(rng.normal(0.0, sigma, size=2))
    return ValveSpec(clearance_mm, roughness, float(friction_scale), float(damping_scale), label)


def valve_friction_n(variant: Variant, valve: ValveSpec) -> float:
    """Coulomb friction F_c of a valve in a pump of this variant."""
    v = variant.valve
    wear_mm = max(0.0, valve.clearance_mm - v.clearance_new_mm)
    return v.coulomb_friction_new_n * (1.0 + v.friction_gain_per_mm * wear_mm) * valve.roughness * valve.friction_scale


def valve_damping_n_s_per_mm(variant: Variant, valve: ValveSpec) -> float:
    """Total viscous damping c: the pump's plus the valve's."""
    v = variant.valve
    wear_mm = max(0.0, valve.clearance_mm - v.clearance_new_mm)
    valve_part = v.damping_new_n_s_per_mm * (1.0 + v.damping_gain_per_mm * wear_mm) * valve.roughness
    return variant.rack.damping_n_s_per_mm + valve_part * valve.damping_scale


def plant_parameters(variant: Variant, valve: ValveSpec, *, stiction: bool = True) -> PlantParameters:
    """Physical plant parameters of ``valve`` fitted to a pump of ``variant``.

    Parameters
    ----------
    variant : Variant
        The pump.
    valve : ValveSpec
        The valve.
    stiction : bool, optional
        If False, breakaway friction equals Coulomb friction (the plant then
        matches the identification model exactly).
    """
    friction_n = valve_friction_n(variant, valve)
    coil = variant.coil
    temp_c = AMBIENT_C if valve.coil_temp_c is None else valve.coil_temp_c
    r20 = coil.resistance_ohm if valve.coil_ohm is None else valve.coil_ohm
    return PlantParameters(
        mass_kg=variant.rack.mass_kg,
        spring_n_per_mm=variant.rack.spring_n_per_mm,
        magnetic_stiffness_n_per_mm=variant.coil.magnetic_stiffness_n_per_mm,
        preload_n=variant.rack.preload_n,
        damping_n_s_per_mm=valve_damping_n_s_per_mm(variant, valve),
        coulomb_friction_n=friction_n,
        stiction_friction_n=friction_n * (variant.valve.stiction_ratio if stiction else 1.0),
        resistance_ohm=resistance_at_ohm(r20, temp_c, coil.temperature_coefficient_per_k),
        inductance_h=variant.coil.inductance_mh * 1e-3,
        force_constant_n_per_a=variant.coil.force_constant_n_per_a,
        amplifier_gain=variant.coil.amplifier_gain,
        amplifier_limit_v=variant.coil.amplifier_limit_v,
        stroke_mm=variant.rack.stroke_mm,
        coil_temp_c=temp_c,
        ambient_c=AMBIENT_C,
        temperature_coefficient_per_k=coil.temperature_coefficient_per_k,
        thermal_capacity_j_per_k=coil.thermal_capacity_j_per_k,
        thermal_resistance_k_per_w=coil.thermal_resistance_k_per_w,
        force_constant_slope_per_mm=coil.force_constant_variation_per_mm,
        force_constant_mid_mm=variant.rack.mid_stroke_mm,
        stribeck_velocity_mm_s=variant.valve.stribeck_velocity_mm_s if stiction else 0.0,
    )


def with_friction(params: PlantParameters, coulomb_n: float, stiction_n: float | None = None) -> PlantParameters:
    """Copy of ``params`` with other friction (for analysis and tests)."""
    return replace(params, coulomb_friction_n=coulomb_n,
                   stiction_friction_n=coulomb_n if stiction_n is None else stiction_n)


def nominal_plant(variant: Variant) -> PlantParameters:
    """The variant's plant with a nominal new valve (no spread between valves).

    This is the plant the controller is designed for and its gains are
    checked against: the pump variant's data-sheet physics, never a
    simulator's.
    """
    preset = variant.valve.presets["new"]
    return plant_parameters(variant, ValveSpec(preset.clearance_mm, preset.roughness, label="nominal new"))
