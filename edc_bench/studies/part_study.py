"""Which part is at fault, over a simulated population (``edc-bench evaluate --parts``, docs/diagnosis.md).

Each case is a kind of pump at a severity: new and worn valves on a sound pump, a sound valve in a pump whose rack
drags, binds at one place or whose friction rises along the stroke, or whose rack-travel sensor reads long, off
its zero, bowed, with a step, noisy, with dropouts or spikes, each at several sizes around its limit, and a worn
valve on a binding rack, and sound pumps at the corners of their return spring's tolerance. Each test's pump has a
spring of its own, drawn within the type's tolerance (``[rack] spring_tolerance_rel``, ``preload_tolerance_rel``), as
pumps of one type differ. Every test runs the bench's whole path (:func:`~edc_bench.bench.run_simulated_test`: the
loop, the period fit, the verdict and the part diagnosis) on a valve drawn with the variant's spread between valves,
each with its own noise seed; a bind, or a sensor's step, sits at a random place within the swing. The study counts, case by case, the part
the bench named and the verdict it gave, and whether it told the technician to replace the valve.
"""

from __future__ import annotations

import dataclasses
import math
from collections import Counter
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from edc_bench.config.models import Variant

#: What a case is, for the table's first column and for what counts as named right.
SOUND, WORN, DRAG, RACK, SENSOR, WORN_ON_RACK = ("sound pump, new valve", "sound pump, worn valve",
                                                  "dragging rack, new valve", "rack, new valve",
                                                  "sensor, new valve", "binding rack, worn valve")


@dataclass(frozen=True)
class PartCase:
    """One kind of pump at one severity.

    Attributes
    ----------
    name : str
        What it is and how bad, for people.
    kind : str
        One of :data:`SOUND`, :data:`WORN`, :data:`DRAG`, :data:`RACK`, :data:`SENSOR`, :data:`WORN_ON_RACK`.
    valve : str
        ``new`` or ``worn`` (the variant's preset's clearance, the valve drawn with the variant's spread).
    rack, sensor : str
        The ``--rack-fault`` and ``--sensor-fault`` specs (``none`` for sound).
    above_limit : bool
        The fault is beyond its ``[diagnosis.parts]`` limit (by its physics): the bench must name its part.
    placed_at_random : bool
        The fault's place (a bind's, or a sensor step's) drawn at random within the swing, test by test.
    pump : str
        The pump's return spring (``spring_rel=..,preload_rel=..`` of ``--rack-fault``); empty: drawn test by test
        within the type's tolerance (``[rack] spring_tolerance_rel``, ``preload_tolerance_rel``), as pumps of one
        type differ.
    """

    name: str
    kind: str
    valve: str = "new"
    rack: str = "none"
    sensor: str = "none"
    above_limit: bool = True
    placed_at_random: bool = False
    pump: str = ""


def part_cases(variant: Variant) -> list[PartCase]:
    """The study's cases for ``variant``: the rack's faults sized in shares of a new valve's friction F_c (the limits'
    unit: a bind's peak, a slope's rise over the swing), the sensor's in its own units (docs/diagnosis.md gives the
    limits); each case beyond its limit or not by that size."""
    from edc_bench.verdict.part import linearity_allowance_mm

    limits = variant.diagnosis.parts
    friction_n = variant.valve.coulomb_friction_new_n
    swing_mm = 2.0 * sum(t.amplitude_mm for t in variant.excitation.active_tones)

    def newton(share: float) -> float:
        return round(share * friction_n, 4)

    spring, preload = variant.rack.spring_tolerance_rel, variant.rack.preload_tolerance_rel
    cases = [PartCase("new valve", SOUND, above_limit=False), PartCase("worn valve", WORN, valve="worn")]
    # pumps at the corners of the spring's tolerance: sound, however their springs differ from the type's
    cases += [PartCase(f"spring {sign * spring:+.0%}, preload {sign * turn * preload:+.0%}", SOUND,
                       above_limit=False, pump=f"spring_rel={sign * spring:g},preload_rel={sign * turn * preload:g}")
              for sign, turn in ((1, 1), (-1, -1), (1, -1), (-1, 1))]
    cases += [PartCase(f"drag {newton(r):g} N ({r:.0%} of F_c)", DRAG, rack=f"drag_n={newton(r)}")
              for r in (0.6, 1.0)]  # beyond uniform_friction_rel with the spread between new valves (8 %, 3 sd)
    cases += [PartCase(f"bind {newton(r):g} N ({r:.0%} of F_c)", RACK, rack=f"bind_n={newton(r)},bind_width_mm=1",
                       above_limit=r > limits.rack_bind_rel, placed_at_random=True) for r in (0.06, 0.3, 1.0, 2.0)]
    cases += [PartCase("bent rack", RACK, rack="bent")]
    cases += [PartCase(f"slope {newton(r) / swing_mm:.4g} N/mm ({r:.0%} of F_c over the swing)", RACK,
                       rack=f"slope_n_per_mm={newton(r) / swing_mm:.6g}", above_limit=r > limits.rack_slope_rel)
              for r in (0.07, 0.25, 0.5)]
    cases += [PartCase(f"gain {g}", SENSOR, sensor=f"gain={g}", above_limit=abs(g - 1) > limits.sensor_gain_rel)
              for g in (1.015, 1.05, 1.08, 0.93)]
    cases += [PartCase(f"zero {o} mm", SENSOR, sensor=f"offset_mm={o}", above_limit=abs(o) > limits.sensor_offset_mm)
              for o in (0.05, 0.15, 0.3)]
    linearity_mm = linearity_allowance_mm(variant, 0)  # against the shipped baselines: simulated pumps
    cases += [PartCase(f"bow {b:.2f} mm", SENSOR, sensor=f"bow_mm={b:.2f}", above_limit=abs(b) > linearity_mm)
              for b in (0.05, round(2.0 * linearity_mm, 2), round(3.0 * linearity_mm, 2))]
    # a step (over about 2 mm) reads the rack above it h off, against the reading at its stop
    cases += [PartCase(f"step {h} mm", SENSOR, sensor=f"step_mm={h},step_width_mm=1",
                       above_limit=h > linearity_mm, placed_at_random=True) for h in (0.05, 0.3, 0.5)]
    stated_mm = variant.sensors.lvdt.noise_sd
    cases += [PartCase(f"noise {n} mm", SENSOR, sensor=f"noise_sd_mm={n}",
                       above_limit=math.hypot(n, stated_mm) > limits.sensor_noise_ratio * stated_mm)
              for n in (0.003, 0.012, 0.02)]
    cases += [PartCase(f"dropouts {r}/s", SENSOR, sensor=f"dropouts_per_s={r}") for r in (0.5, 2.0)]
    cases += [PartCase(f"spikes {r}/s", SENSOR, sensor=f"spikes_per_s={r}") for r in (1.0, 3.0)]
    cases += [PartCase(f"worn valve, bind {newton(1.0):g} N", WORN_ON_RACK, valve="worn",
                       rack=f"bind_n={newton(1.0)},bind_width_mm=1", placed_at_random=True)]
    return cases


@dataclass(frozen=True)
class CaseResult:
    """What the bench said over one case's tests."""

    case: PartCase
    tests: int
    parts: dict[str, int]
    verdicts: dict[str, int]
    told_replace: int
    pairs: dict[tuple[str, str], int]  # (part, verdict): tests

    @property
    def named_right(self) -> int:
        """Tests whose part (and, for valves on a sound pump, verdict) is what the case is."""
        return sum(n for (part, verdict), n in self.pairs.items() if _right(self.case, part, verdict))


def _right(case: PartCase, part: str, verdict: str) -> bool:
    from edc_bench.verdict.part_sections import Part

    if not case.above_limit:  # below its limit the part is reported as sound: the valve judged (new: PASS)
        return part in (Part.NONE, Part.VALVE_OR_RACK) and verdict == "PASS"
    if case.kind == SOUND:
        return part == Part.NONE and verdict == "PASS"
    if case.kind == WORN:
        return verdict == "FAIL" and part in (Part.NONE, Part.VALVE_OR_RACK)
    if case.kind == DRAG:
        return part in (Part.VALVE_OR_RACK, Part.RACK)
    if case.kind in (RACK, WORN_ON_RACK):
        return part == Part.RACK
    return part == Part.SENSOR


def _one(job: tuple[str, PartCase, dict, int, float, str]) -> tuple[str, str, bool]:
    """One test: the part named, the verdict, and whether the technician was told to replace the valve."""
    from edc_bench.bench import run_simulated_test
    from edc_bench.config import load_variant
    from edc_bench.physics.valve import ValveSpec
    from edc_bench.records.advice import Action

    variant_name, case, valve, seed, place_mm, pump = job
    variant = load_variant(variant_name)
    rack, sensor = case.rack, case.sensor
    if case.placed_at_random and case.kind == SENSOR:
        sensor = f"{sensor},step_at_mm={place_mm:.2f}"
    elif case.placed_at_random:
        rack = f"{rack},bind_at_mm={place_mm:.2f}"
    rack = pump if rack == "none" else f"{rack},{pump}"
    result = run_simulated_test(variant, ValveSpec(**valve), seed, rack_fault=rack, sensor_fault=sensor,
                                valve_id=f"{case.name} {seed}")
    part = result.judgement.part
    return (str(part.part) if part is not None else "none", str(result.verdict),
            result.advice.action == Action.REPLACE)


def run_part_study(variant: Variant, tests_per_case: int = 10, seed: int = 4100, workers: int = 2,
                   cases: Sequence[PartCase] | None = None,
                   progress: Callable[[int, int], None] | None = None) -> list[CaseResult]:
    """Run every case's tests (each on a valve of its own, with its own noise) and count what the bench said.

    Parameters
    ----------
    variant : Variant
        The pump type (a shipped variant's name is what the worker processes load).
    tests_per_case : int
    seed : int
        Seeds the valves' spread, the binds' places and the tests' noise.
    workers : int
        Processes (1: in this one).
    cases : sequence of PartCase, optional
        The cases (:func:`part_cases` by default).
    progress : callable, optional
        Called with (tests done, tests in all).
    """
    from edc_bench.config.loader import variant_argument
    from edc_bench.physics.valve import sample_valve

    chosen = list(cases) if cases is not None else part_cases(variant)
    rng = np.random.default_rng(seed)
    pumps = np.random.default_rng([seed, 0x9A3])  # each test's pump (a stream of its own: the valves as before)
    spring, preload = variant.rack.spring_tolerance_rel, variant.rack.preload_tolerance_rel
    swing = sum(t.amplitude_mm for t in variant.excitation.active_tones)
    mid = variant.rack.mid_stroke_mm
    jobs = []
    for c, case in enumerate(chosen):
        clearance = variant.valve.presets[case.valve].clearance_mm
        for n in range(tests_per_case):
            valve = sample_valve(variant, clearance, rng, variant.valve.presets[case.valve].roughness,
                                 label=f"{case.valve} (spread)")
            fields = dataclasses.asdict(valve)
            place_mm = float(rng.uniform(mid - 0.7 * swing, mid + 0.7 * swing))
            drawn = pumps.uniform(-1.0, 1.0, 2) * (spring, preload)
            pump = case.pump or f"spring_rel={drawn[0]:.4f},preload_rel={drawn[1]:.4f}"
            jobs.append((variant_argument(variant), case, fields, seed + 1000 * c + n, place_mm, pump))
    outcomes: list[tuple[str, str, bool]] = []
    if workers > 1:
        import multiprocessing

        with multiprocessing.get_context("spawn").Pool(workers) as pool:
            for outcome in pool.imap(_one, jobs, chunksize=2):
                outcomes.append(outcome)
                if progress:
                    progress(len(outcomes), len(jobs))
    else:
        for job in jobs:
            outcomes.append(_one(job))
            if progress:
                progress(len(outcomes), len(jobs))
    results = []
    for c, case in enumerate(chosen):
        mine = outcomes[c * tests_per_case:(c + 1) * tests_per_case]
        results.append(CaseResult(case=case, tests=len(mine), parts=dict(Counter(p for p, _, _ in mine)),
                                  verdicts=dict(Counter(v for _, v, _ in mine)),
                                  told_replace=sum(r for _, _, r in mine),
                                  pairs=dict(Counter((p, v) for p, v, _ in mine))))
    return results


PART_COLUMNS = ("none", "valve or rack", "rack", "rack-travel sensor")
VERDICT_COLUMNS = ("PASS", "MARGINAL", "FAIL", "INVALID")


def study_json(results: Sequence[CaseResult]) -> dict[str, object]:
    """A study as ``evaluate --parts --json`` prints it and the docs store it: the headline and every case."""
    return {"summary": dataclasses.asdict(part_summary(results)),
            "cases": [{"case": r.case.name, "kind": r.case.kind, "beyond_limit": r.case.above_limit, "tests": r.tests,
                       "parts": r.parts, "verdicts": r.verdicts, "told_replace": r.told_replace,
                       "named_right": r.named_right} for r in results]}


def part_table(results: Sequence[CaseResult]) -> str:
    """The confusion matrix as a Markdown table: per case, the parts named, the verdicts, "replace the valve"."""
    head = ["case", "what it is", "beyond its limit", "tests", *(f"named: {p}" for p in PART_COLUMNS),
            *VERDICT_COLUMNS, "told: replace the valve", "named right"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for r in results:
        row = [r.case.name, r.case.kind, "yes" if r.case.above_limit else "no", str(r.tests),
               *(str(r.parts.get(p, 0)) for p in PART_COLUMNS), *(str(r.verdicts.get(v, 0)) for v in VERDICT_COLUMNS),
               str(r.told_replace), f"{r.named_right}/{r.tests}"]
        lines.append("| " + " | ".join(row) + " |")
    return "\n".join(lines)


@dataclass(frozen=True)
class PartSummary:
    """The study's figures the issue's bar is set in."""

    faults_named: int  # non-valve faults beyond their limit, their part named
    faults: int
    sound_valves_told_replace: int  # sound valves in a pump with a bind, a slope or a sensor fault beyond its limit
    sound_valves_at_fault: int
    worn_failed: int  # worn valves on a sound pump: FAIL
    worn: int
    worn_on_rack_passed: int
    worn_on_rack: int
    below_limit_named: int  # faults below their limit whose part was named anyway
    below_limit: int


def part_summary(results: Sequence[CaseResult]) -> PartSummary:
    """The headline figures of a study."""
    def total(select: Callable[[CaseResult], bool], count: Callable[[CaseResult], int]) -> int:
        return sum(count(r) for r in results if select(r))

    faulty = lambda r: r.case.above_limit and r.case.kind in (DRAG, RACK, SENSOR)  # noqa: E731
    pointing = lambda r: r.case.above_limit and r.case.kind in (RACK, SENSOR)  # noqa: E731
    below = lambda r: not r.case.above_limit and r.case.kind in (RACK, SENSOR)  # noqa: E731
    return PartSummary(
        faults_named=total(faulty, lambda r: r.named_right), faults=total(faulty, lambda r: r.tests),
        sound_valves_told_replace=total(pointing, lambda r: r.told_replace),
        sound_valves_at_fault=total(pointing, lambda r: r.tests),
        worn_failed=total(lambda r: r.case.kind == WORN, lambda r: r.verdicts.get("FAIL", 0)),
        worn=total(lambda r: r.case.kind == WORN, lambda r: r.tests),
        worn_on_rack_passed=total(lambda r: r.case.kind == WORN_ON_RACK, lambda r: r.verdicts.get("PASS", 0)),
        worn_on_rack=total(lambda r: r.case.kind == WORN_ON_RACK, lambda r: r.tests),
        below_limit_named=total(below, lambda r: r.tests - r.named_right), below_limit=total(below, lambda r: r.tests))


def summary_lines(s: PartSummary) -> list[str]:
    """The headline figures in words."""
    share = s.faults_named / s.faults if s.faults else float("nan")
    return [
        f"faults of the rack or the sensor beyond their limit, their part named: {s.faults_named} of {s.faults} "
        f"({share:.1%})",
        f"sound valves in a pump with a bind, a slope or a sensor fault beyond its limit told to replace the valve: "
        f"{s.sound_valves_told_replace} of {s.sound_valves_at_fault}",
        f"worn valves on a sound pump judged FAIL: {s.worn_failed} of {s.worn}",
        f"worn valves on a binding rack judged PASS: {s.worn_on_rack_passed} of {s.worn_on_rack}",
        f"faults below their limit named anyway (or not PASS): {s.below_limit_named} of {s.below_limit}",
    ]
