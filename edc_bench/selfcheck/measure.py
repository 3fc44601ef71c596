"""Measure the reference valve: the rig at rest, then a bench test of the valve, and the figures compared.

The figures (:class:`ReferenceValues`), and which drift each one shows:

- ``lvdt_zero_mm``: the rack position read at rest (:mod:`~edc_bench.selfcheck.rest`): the LVDT's zero;
- ``current_zero_a``: the coil current read at rest, no drive: the current sensor's zero;
- ``coil_r20_ohm``: the coil's resistance measured in the test (drive over current), referred to 20 degC: the
  current sensor's gain (a sensor that reads 3 % high measures the coil 3 % low);
- ``a0_v_per_mm``: the spring rate the test identified, in volts per mm of the LVDT's reading: the LVDT's gain
  (an LVDT that reads 3 % long makes every millimetre 3 % cheaper);
- ``af_v`` and ``a1_v_s_per_mm``: the reference valve's friction and damping.

The bench's drive is its own command, so the figures in volts carry no sensor's error; what the current sensor
changes in a test is the coil's resistance, which the bench uses to refer af and a1 to the reference coil. The
self-check therefore compares af, a1 and a0 in volts with the coil as it was, referred to 20 degC by the coil's
temperature stated (``--coil-temp-c``; a rested coil at 20 degC by default), not by the resistance measured:
a drifted current sensor then moves the coil's resistance alone, and an LVDT's gain moves a0 and a1 together.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable
from typing import Any

from edc_bench.canlib import can
from edc_bench.config.models import Variant
from edc_bench.physics.valve import ValveSpec
from edc_bench.engine.problems import Problem
from edc_bench.runtime.clock import Clock
from edc_bench.verdict.part import part_reasons
from edc_bench.verdict.part_sections import PartFinding, Signature
from edc_bench.selfcheck.compare import ReferenceValues
from edc_bench.selfcheck.rest import RestReading, measure_rest


def reference_values(variant: Variant, rest: RestReading, result: Any,
                     coil_temp_c: float | None = None) -> ReferenceValues:
    """The figures of a rest reading and a bench test of the reference valve (pure).

    Parameters
    ----------
    variant : Variant
        The reference valve's variant (its reference coil and temperature coefficient).
    rest : RestReading
        The rig at rest.
    result : BenchResult
        The reference valve's bench test (run without classification).
    coil_temp_c : float, optional
        The coil's temperature at the start of the test (20 degC if not given).

    Returns
    -------
    ReferenceValues
    """
    from edc_bench.physics.coil import resistance_20c_ohm, volts_at_coil
    from edc_bench.physics.feedforward import inductive_shares
    from edc_bench.verdict.judgement import measured_resistance_ohm
    from edc_bench.verdict.verdicts import Verdict

    temp_c = 20.0 if coil_temp_c is None else float(coil_temp_c)
    alpha = variant.coil.temperature_coefficient_per_k
    inductive = inductive_shares(variant)._asdict()
    r_ref, r_hat = variant.coil.resistance_ohm, measured_resistance_ohm(result.trace, variant)

    def volts_20c(name: str) -> float:
        entry = result.parameters.get(name)
        if entry is None or entry.value is None or not math.isfinite(entry.value):
            return math.nan
        return float(resistance_20c_ohm(volts_at_coil(inductive[name], entry.value, r_ref, r_hat), temp_c, alpha))

    coil = result.judgement.coil
    coil_r20_ohm = math.nan if coil is None or coil.resistance_20c_ohm is None else coil.resistance_20c_ohm
    # the part diagnosis reads the rig's own LVDT here: its signal's findings are the self-check's (the LVDT's zero
    # and gain it compares itself, the rack's friction is the reference valve's and the rig's mechanics); a test
    # INVALID for them alone is trusted for its figures
    part = result.judgement.part
    signal = tuple(_signal_words(f) for f in (part.beyond if part is not None else ()) if f.signature in SIGNAL)
    own = result.judgement.problems & ~Problem.PUMP_FAULT
    said = set(part_reasons(part)) if part is not None else set()
    problems = tuple(r for r in result.reasons if r not in said) if result.verdict == Verdict.INVALID and own else ()
    return ReferenceValues(
        lvdt_zero_mm=rest.lvdt_zero_mm, current_zero_a=rest.current_zero_a,
        coil_r20_ohm=float(coil_r20_ohm),
        a0_v_per_mm=volts_20c("a0"), af_v=volts_20c("af"), a1_v_s_per_mm=volts_20c("a1"),
        lvdt_at_floor=rest.lvdt_at_floor, test_problems=problems, coil_temp_c=temp_c, signal_faults=signal)


#: The part diagnosis's signatures of a sensor's own signal (the LVDT's, in the self-check)
SIGNAL = (Signature.SENSOR_NOISE, Signature.SENSOR_SPIKES, Signature.SENSOR_DROPOUTS)


def _signal_words(finding: PartFinding) -> str:
    figure = 0.0 if finding.figure is None else float(finding.figure)
    if finding.signature is Signature.SENSOR_NOISE:
        return f"noise {figure:.1f}x the stated"
    return f"{figure:.0f} {'spikes' if finding.signature is Signature.SENSOR_SPIKES else 'dropouts'}"


def _test_options(coil_temp_c: float | None, valve_id: str, observer: Any) -> Any:
    from edc_bench.bench import BenchOptions

    # not classified: the reference valve is not judged, only measured; the whole length, so every check runs
    # the same test
    return BenchOptions(valve_id=valve_id, classify=False, check_gains=False, coil_temp_c=coil_temp_c,
                        observer=observer)


def measure_on_bus(bus: can.BusABC, clock_factory: Callable[[], Clock], variant: Variant, *, valve_id: str = "",
                   coil_temp_c: float | None = None, observer: Any = None) -> tuple[ReferenceValues, Any]:
    """Measure the reference valve on a rig's bus: the rig at rest, then its bench test.

    Parameters
    ----------
    bus : can.BusABC
        The bench's bus to the rig.
    clock_factory : callable
        Makes a new clock for each part (``RealTimeClock``).
    variant : Variant
        The reference valve's variant.
    valve_id : str, optional
        The reference valve's id, for the test.
    coil_temp_c : float, optional
        The coil's temperature at the start (20 degC, a rested coil, if not given).
    observer : LoopObserver, optional
        Shown the test as it runs.

    Returns
    -------
    (ReferenceValues, BenchResult)
    """
    from edc_bench.bench import run_bench_test

    rest = measure_rest(bus, clock_factory(), variant)
    result = run_bench_test(bus, clock_factory(), variant, _test_options(coil_temp_c, valve_id, observer))
    return reference_values(variant, rest, result, coil_temp_c), result


_channels = itertools.count()


def measure_simulated(variant: Variant, valve: ValveSpec | str = "new", seed: int = 0, *, drift: Any = None,
                      firmware: str = "python", valve_id: str = "", coil_temp_c: float | None = None,
                      observer: Any = None) -> tuple[ReferenceValues, Any]:
    """Measure the reference valve on the simulated rig, in process and in simulated time.

    Parameters
    ----------
    variant : Variant
        The reference valve's variant.
    valve : ValveSpec or str
        The simulated reference valve (``new``, or physical values).
    seed : int
        Seed of the rig's sensor noise (the rest reading uses a seed of its own drawn from it).
    drift : SensorDrift or str, optional
        The simulated rig's sensor drift (``lvdt_offset_mm=0.05``): none by default.
    firmware : str
        The simulated rig's firmware (``python`` or ``c``).
    valve_id, coil_temp_c, observer :
        As :func:`measure_on_bus`.

    Returns
    -------
    (ReferenceValues, BenchResult)
    """
    from edc_bench.bench import run_simulated_test
    from edc_bench.physics.valve import parse_valve_spec
    from edc_bench.runtime.clock import SimulatedClock
    from edc_bench.sim.drift import SensorDrift, parse_rig_drift
    from edc_bench.sim.inprocess import InProcessRig
    from edc_bench.sim.lockstep_bus import lockstep_pair
    from edc_bench.sim.rig import RigOptions, SimulatedRig

    spec = valve if isinstance(valve, ValveSpec) else parse_valve_spec(valve, variant)
    sensors = parse_rig_drift(drift) if isinstance(drift, str) else (drift or SensorDrift())
    # the rig at rest: the same valve and sensors, a rig of its own (the test's rig starts its clock at 0)
    rig = SimulatedRig(variant, spec, seed + 7919, RigOptions(firmware=firmware, drift=sensors))
    bench_end, rig_end = lockstep_pair(f"edc-bench-selfcheck-{next(_channels)}")
    with bench_end, rig_end:
        rest = measure_rest(bench_end, SimulatedClock(InProcessRig(rig_end, rig)), variant)
    result = run_simulated_test(variant, spec, seed, firmware=firmware, drift=sensors,
                                options=_test_options(coil_temp_c, valve_id or spec.label, observer))
    return reference_values(variant, rest, result, coil_temp_c), result


__all__ = ["measure_on_bus", "measure_simulated", "reference_values"]
