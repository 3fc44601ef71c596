"""The figures of docs/simulation.md: the simulated plant's physics, the valve presets, the adapter model.

Live figures come from the physics (``edc_bench.physics``) and the adapter model (``edc_bench.sim.adapter``);
two measurements run simulated tests: ``simulation-default-test`` (the coil's warming, the replies' age through
``usb-fs``) and ``simulation-batch-usb-fs`` (the batch path against the full loop through ``usb-fs``).
"""

from __future__ import annotations

import math
from typing import Any

from figures.common import measurement, percent, span, stored, table

#: The adapter preset the page describes.
ADAPTER = "usb-fs"
#: Valves of the batch-against-full-loop comparison, and their sensor seed (as tests/population/test_batch.py).
BATCH_VALVES = ("new", "worn", "faulty")
BATCH_SEED = 1
#: Simulated seconds the adapter model's round trips are drawn over (the USB frames drift through every phase).
ROUND_TRIP_SPAN_S = 30.0


def shipped_variants() -> dict[str, Any]:
    """The variants shipped in configs/, loaded, by name."""
    from edc_bench.config import available_variants, load_variant
    from edc_bench.config.loader import is_shipped

    return {name: load_variant(path) for name, path in available_variants().items() if is_shipped(path)}


def hold_current_a(variant: Any) -> float:
    """Coil current that holds the rack at mid-stroke: (k' x_m + F_pre) / k_i."""
    from edc_bench.physics.valve import nominal_plant

    p = nominal_plant(variant)
    return (p.net_stiffness_n_per_mm * variant.rack.mid_stroke_mm + p.preload_n) / p.force_constant_n_per_a


# -- live: the plant ----------------------------------------------------------------------------------------------


def plant_table() -> str:
    """Each shipped variant's plant with a new valve: coil time constant, natural frequency, damping, hold current."""
    from edc_bench.physics.valve import nominal_plant
    from edc_bench.sim.plant import Plant

    rows = []
    for name, variant in shipped_variants().items():
        params = nominal_plant(variant)
        plant = Plant(params)
        rows.append((f"`{name}`", f"{params.inductance_h / params.resistance_ohm * 1e3:.2f} ms",
                     f"{plant.natural_frequency_rad_s() / (2 * math.pi):.2f} Hz", f"{plant.damping_ratio():.3f}",
                     f"{hold_current_a(variant):.1f} A"))
    return table(("variant", "coil L/R at 20 degC", "natural frequency sqrt(k'/m) / 2 pi", "damping ratio, new valve",
                  "current holding mid-stroke"), rows)


def presets_table(variant_name: str = "p-edc-default") -> str:
    """The variant's valve presets, physically, with af and a1 against its new valve (``feedforward_truth``)."""
    from edc_bench.config import load_variant
    from edc_bench.physics.feedforward import feedforward_truth
    from edc_bench.physics.valve import (
        ValveSpec,
        plant_parameters,
        valve_damping_n_s_per_mm,
        valve_friction_n,
    )

    variant = load_variant(variant_name)
    presets = variant.valve.presets
    truth = {name: feedforward_truth(plant_parameters(variant, ValveSpec(p.clearance_mm, p.roughness)))
             for name, p in presets.items()}
    new = truth["new"]
    rows = []
    for name, p in presets.items():
        spec = ValveSpec(p.clearance_mm, p.roughness)
        af, a1 = f"{truth[name].af:.3f} V", f"{truth[name].a1:.4f} V s/mm"
        if name != "new":
            af += f" ({percent(truth[name].af / new.af - 1, 0, sign=True)})"
            a1 += f" ({percent(truth[name].a1 / new.a1 - 1, 0, sign=True)})"
        rows.append((f"`{name}`", f"{p.clearance_mm:g} mm", f"{p.roughness:g}", f"{valve_friction_n(variant, spec):.2f} N",
                     f"{valve_damping_n_s_per_mm(variant, spec):.4f} N s/mm", af, a1))
    return table(("preset", "clearance", "roughness", "F_c", "c (pump + valve)", "af (vs new)", "a1 (vs new)"), rows)


# -- live: the adapter model --------------------------------------------------------------------------------------


def model_round_trips_ms(adapter: str = ADAPTER, seed: int = 0) -> list[float]:
    """Command-to-reply times of the adapter model, one command a millisecond, the rig answering at once."""
    import numpy as np

    from edc_bench.sim.adapter import PRESETS

    model = PRESETS[adapter]
    rng = np.random.default_rng(seed)
    to_rig = to_bench = -math.inf
    times = []
    for k in range(int(ROUND_TRIP_SPAN_S * 1e3)):
        sent_s = k * 1e-3
        to_rig = model.delivery_s(sent_s, rng, to_rig)
        to_bench = model.delivery_s(to_rig, rng, to_bench)
        times.append((to_bench - sent_s) * 1e3)
    return times


def usb_fs_bullet() -> str:
    """The ``--adapter usb-fs`` bullet: the preset's settings, the model's round trip, the replies' age measured."""
    from edc_bench.sim.adapter import PRESETS

    model = PRESETS[ADAPTER]
    trips = model_round_trips_ms()
    ages = stored("simulation-default-test")["usb_fs"]["reply_age_ticks"]
    age_text = " or ".join(str(age) for age in sorted(ages, key=int))
    return (f"- `--adapter {ADAPTER}` (on `edc-bench test` in simulation, and on\n"
            f"  `edc-bench rig`): {model.latency_s * 1e3:g} ms latency, {model.jitter_s * 1e3:g} ms jitter, "
            f"{model.usb_frame_s * 1e3:g} ms USB frames, {model.usb_drift_ppm:g} ppm\n"
            f"  drift: {span(min(trips), max(trips), unit='ms')} round trip in the model (the rig answering at once, "
            f"{ROUND_TRIP_SPAN_S:g} s of commands),\n"
            f"  replies used {age_text} ticks after their command in a simulated test (`simulation-default-test`).")


# -- measurements -------------------------------------------------------------------------------------------------


@measurement("simulation-default-test", minutes=0.15)
def default_test() -> dict[str, Any]:
    """30 s tests of a new valve on ``p-edc-default`` (seed 0): without latency (the coil's warming) and through
    ``usb-fs`` (the replies' age in ticks, as shares of the replies)."""
    from edc_bench.bench import run_simulated_test
    from edc_bench.config import load_variant

    variant = load_variant("p-edc-default")
    plain = run_simulated_test(variant, "new", 0, full_length=True, classify=False)
    usb = run_simulated_test(variant, "new", 0, adapter=ADAPTER, full_length=True, classify=False)
    coil = plain.simulation.coil
    replies = sum(usb.outcome.reply_age_ticks.values())
    return {
        "duration_s": variant.excitation.duration_s,
        "coil": {"temp_start_c": round(coil.temp_start_c, 2), "temp_end_c": round(coil.temp_end_c, 2),
                 "resistance_start_ohm": round(coil.resistance_start_ohm, 4),
                 "resistance_end_ohm": round(coil.resistance_end_ohm, 4)},
        "usb_fs": {"reply_age_ticks": {str(age): round(n / replies, 3)
                                       for age, n in sorted(usb.outcome.reply_age_ticks.items())}},
    }


@measurement("simulation-batch-usb-fs", minutes=0.5)
def batch_against_full_loop() -> dict[str, Any]:
    """af and a1 of the batch path against the full loop, both through ``usb-fs``: the new, worn and faulty presets
    of ``p-edc-default``, seed 1 (the case tests/population/test_batch.py checks)."""
    from edc_bench.bench import run_simulated_test
    from edc_bench.config import load_variant
    from edc_bench.physics.valve import parse_valve_spec
    from edc_bench.population.batch import run_batch
    from edc_bench.sim.adapter import parse_adapter

    variant = load_variant("p-edc-default")
    specs = [parse_valve_spec(name, variant) for name in BATCH_VALVES]
    batch = run_batch(variant, specs, [BATCH_SEED] * len(specs), adapter=parse_adapter(ADAPTER))
    names = ("a3", "a2", "a1", "a0", "b", "af")
    deviation: dict[str, dict[str, float]] = {}
    for j, (name, spec) in enumerate(zip(BATCH_VALVES, specs)):
        full = run_simulated_test(variant, spec, BATCH_SEED, check_gains=False, classify=False, adapter=ADAPTER)
        deviation[name] = {p: round(float(batch.parameters[j, names.index(p)] / full.parameters[p].value - 1), 5)
                           for p in ("af", "a1")}
    return {"valves": list(BATCH_VALVES), "relative_deviation": deviation}


def coil_heating_sentence() -> str:
    """How much the coil warms in a test of a new valve on the default variant (``simulation-default-test``)."""
    from edc_bench.config import load_variant

    data = stored("simulation-default-test")
    coil = data["coil"]
    variant = load_variant("p-edc-default")
    return (f"In a {data['duration_s']:g} s test of a new valve on `p-edc-default` (its coil holds the rack at "
            f"mid-stroke with {hold_current_a(variant):.1f} A) the coil warms from {coil['temp_start_c']:.0f} to "
            f"{coil['temp_end_c']:.1f} degC, and its resistance from {coil['resistance_start_ohm']:.3f} to "
            f"{coil['resistance_end_ohm']:.3f} ohm (`python docs/regenerate.py --measure simulation-default-test`).")


def batch_sentence() -> str:
    """How closely the batch path's af and a1 follow the full loop's through ``usb-fs``."""
    data = stored("simulation-batch-usb-fs")
    worst = max(abs(v) for valve in data["relative_deviation"].values() for v in valve.values())
    valves = ", ".join(data["valves"])
    return (f"On the {valves} presets of `p-edc-default` the batch path's af and a1 agree with the full loop's "
            f"through `{ADAPTER}` within {percent(worst, 1)} (`simulation-batch-usb-fs`; "
            "`tests/population/test_batch.py` checks 1 %).")


def host_queue_sentence() -> str:
    """How long the server's per-host output queue lasts at 1 kHz: one line (replies) or two (with commands) a
    tick. Indented by two spaces: it sits in a list item."""
    from edc_bench.protocol import RIG_FEEDBACK_ID
    from edc_bench.sim.server import HOST_QUEUE_BYTES
    from edc_bench.sim.slcan import SlcanDevice

    line_bytes = len(SlcanDevice.format_frame(RIG_FEEDBACK_ID, bytes(8)))
    seconds = [HOST_QUEUE_BYTES / (lines * line_bytes * 1e3) for lines in (2, 1)]
    return (f"  The queue holds {HOST_QUEUE_BYTES // 1024} KiB (`HOST_QUEUE_BYTES`): {span(*seconds)} s of a 1 kHz\n"
            f"  test's traffic to one host (one or two {line_bytes}-byte lines a tick); the kernel's socket buffer\n"
            "  comes on top.")
