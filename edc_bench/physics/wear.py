"""When a valve is faulty, by its physics (the ground truth of a simulated valve).

A valve is faulty when the force it opposes to the rack at the variant's
reference speed, Coulomb friction plus damping, exceeds the variant's limit.
The label of a simulated valve comes from this, never from identified
values.
"""

from __future__ import annotations

from edc_bench.config.models import Variant
from edc_bench.physics.valve import ValveSpec, valve_damping_n_s_per_mm, valve_friction_n


def resisting_force_n(variant: Variant, valve: ValveSpec) -> float:
    """Friction plus damping force at the variant's reference speed."""
    d = variant.diagnosis
    return valve_friction_n(variant, valve) + valve_damping_n_s_per_mm(variant, valve) * d.resistance_speed_mm_s


def is_faulty(variant: Variant, valve: ValveSpec) -> bool:
    """Ground truth: the valve's resisting force exceeds the variant's limit."""
    return resisting_force_n(variant, valve) > variant.diagnosis.resistance_limit_n


def clearance_for_resisting_force(variant: Variant, target_n: float, roughness: float = 1.0) -> float:
    """Clearance of a nominal valve (no spread) whose resisting force is ``target_n`` (bisection)."""
    lo, hi = variant.valve.clearance_new_mm, 2.0
    if resisting_force_n(variant, ValveSpec(hi, roughness)) < target_n:
        raise ValueError(f"no clearance below {hi} mm reaches {target_n} N")
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if resisting_force_n(variant, ValveSpec(mid, roughness)) < target_n:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)
