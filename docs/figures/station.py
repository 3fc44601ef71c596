"""The figures of docs/station.md that are not in its images (docs/make_images.py draws those).

``station-online-vs-period-fit`` measures how far the feedforward's online af and a1 end from the period fit's
(the features the verdict uses), which the report's convergence plot shows side by side.
"""

from __future__ import annotations

from typing import Any

from figures.common import measurement, percent, stored

#: Variants compared: one the linear model fits, one it fits only roughly.
VARIANTS = ("p-edc-default", "p-edc-hard")


def _online_against_period_fit(variant_name: str, seed: int = 0) -> dict[str, float]:
    """Relative difference of the online af and a1 at the end of a new valve's test from the period fit's."""
    from edc_bench.bench import run_simulated_test
    from edc_bench.config import load_variant

    result = run_simulated_test(load_variant(variant_name), "new", seed, classify=False)
    return {name: round(float(result.trace[f"{name}_hat"][-1] / result.parameters[name].value - 1), 4)
            for name in ("af", "a1")}


@measurement("station-online-vs-period-fit", minutes=0.1)
def online_vs_period_fit() -> dict[str, Any]:
    """For a new valve (seed 0) on each of :data:`VARIANTS`: online af and a1 at the end against the period fit."""
    return {name: _online_against_period_fit(name) for name in VARIANTS}


def convergence_sentence() -> str:
    """How far the online estimates end from the period fit on each compared variant (a new valve's test)."""
    data = stored("station-online-vs-period-fit")
    parts = [f"by {percent(d['af'], 0, sign=True)} and {percent(d['a1'], 0, sign=True)} on `{name}`"
             for name, d in data.items()]
    return ("At the end of a new valve's simulated test the online af and a1 differ from the period fit's "
            + ", and ".join(parts) + " (`python docs/regenerate.py --measure station-online-vs-period-fit`).")


def advice_table() -> str:
    """The technician's line for each outcome (edc_bench.records.advice), as the code gives it."""
    from edc_bench.engine.outcome import AbortKind
    from edc_bench.engine.problems import Problem
    from edc_bench.records.advice import advice
    from edc_bench.verdict.part_sections import Part, PartDiagnosis, PartFinding, Signature

    def found(signature: Signature, part: Part) -> PartDiagnosis:
        beyond = PartFinding(signature=signature, part=part, figure=1.0, limit=0.1, beyond=True)
        return PartDiagnosis(part=part, valve_judged=part is Part.VALVE_OR_RACK, findings=[beyond])

    even = found(Signature.UNIFORM_FRICTION, Part.VALVE_OR_RACK)
    parts = [("PASS", Problem.NONE, None, even, "a reusable valve, its friction 25 % or more above new along the "
                                                "whole stroke"),
             ("FAIL", Problem.NONE, None, even, "a worn valve: its friction the same along the stroke, as a rack "
                                                "that drags evenly"),
             ("INVALID", Problem.PUMP_FAULT, None, found(Signature.RACK_BIND, Part.RACK), "the rack binds at one "
                                                                                          "place"),
             ("INVALID", Problem.PUMP_FAULT, None, found(Signature.RACK_SLOPE, Part.RACK), "the rack's friction "
                                                                                           "changes along its stroke"),
             ("INVALID", Problem.PUMP_FAULT, None, found(Signature.SENSOR_GAIN, Part.SENSOR), "the rack-travel "
                                                                                              "sensor reads long"),
             ("INVALID", Problem.PUMP_FAULT, None, found(Signature.SENSOR_ZERO, Part.SENSOR), "its zero is off"),
             ("INVALID", Problem.PUMP_FAULT, None, found(Signature.SENSOR_LINEARITY, Part.SENSOR), "it reads the "
                                                                                                   "swing unevenly"),
             ("INVALID", Problem.PUMP_FAULT, None, found(Signature.SENSOR_NOISE, Part.SENSOR), "it is noisy"),
             ("INVALID", Problem.PUMP_FAULT | Problem.ABORTED, AbortKind.RIG_FAULT,
              found(Signature.SENSOR_DROPOUTS, Part.SENSOR), "its reading drops out (the rig tripped on it)"),
             ("INVALID", Problem.PUMP_FAULT, None, found(Signature.SENSOR_SPIKES, Part.SENSOR), "its reading spikes")]
    cases = [("PASS", Problem.NONE, None, "a reusable valve"),
             ("FAIL", Problem.NONE, None, "a worn valve, in a record from before the part diagnosis"),
             ("FAIL", Problem.COIL_OUT_OF_SPEC, None, "a coil out of its spec"),
             ("MARGINAL", Problem.NONE, None, "near the boundary"),
             ("INVALID", Problem.ABORTED, AbortKind.SILENCE, "the rig stopped answering"),
             ("INVALID", Problem.ABORTED, AbortKind.OFF_REFERENCE, "the rack did not follow"),
             ("INVALID", Problem.ABORTED, AbortKind.FOREIGN_COMMAND, "another host on the bus"),
             ("INVALID", Problem.TIMING, None, "the PC held the loop up"),
             ("INVALID", Problem.MODEL_DOES_NOT_FIT, None, "the pump does not fit its variant"),
             ("INVALID", Problem.DRIFTING, None, "af and a1 still drifting"),
             ("INVALID", Problem.NOT_CALIBRATED, None, "no new-valve baseline")]
    rows = ["| verdict | when | what to do |", "|---|---|---|"]
    rows += [f"| {verdict} | {when} | {advice(verdict, problems, kind).words} |"
             for verdict, problems, kind, when in cases]
    rows += [f"| {verdict} | {when} | {advice(verdict, problems, kind, part).words} |"
             for verdict, problems, kind, part, when in parts]
    return "\n".join(rows)


def retest_table() -> str:
    """What a MARGINAL and its retest decide under the default ``[retest]`` rule (edc_bench.verdict.retest)."""
    from edc_bench.config.models import RetestSection
    from edc_bench.verdict.retest import decide

    rule = RetestSection()
    rows = ["| first test | retest | decision | what to do |", "|---|---|---|---|"]
    for second in ("PASS", "MARGINAL", "FAIL", "INVALID"):
        decision = decide(second, rule, "not judged: check the mounting" if second == "INVALID" else "")
        rows.append(f"| MARGINAL | {second} | {decision.verdict} | {decision.words} |")
    return "\n".join(rows)


def shift_summary() -> str:
    """The shift summary file that ``python docs/make_images.py session`` wrote (the real app's), as a text block."""
    from pathlib import Path

    text = (Path(__file__).resolve().parent.parent / "images" / "session-shift-summary.txt").read_text()
    return "```text\n" + text.rstrip() + "\n```"
