"""The part diagnosis in words: each finding's sentence, and what the technician does about the part at fault.

Made here only, from the typed :class:`~edc_bench.verdict.part_sections.PartDiagnosis` (a record's, or a test's
just judged): the advice (:mod:`edc_bench.records.advice`), the reasons and the report all speak from it.
"""

from __future__ import annotations

import math

from edc_bench.verdict.part_sections import Part, PartDiagnosis, PartFinding, Signature


def _figure(finding: PartFinding) -> float:
    return math.nan if finding.figure is None else float(finding.figure)


def finding_words(finding: PartFinding) -> str:
    """What one finding measured, against its limit, in a sentence for the engineer."""
    x, limit = _figure(finding), finding.limit
    s = finding.signature
    if s is Signature.SENSOR_DROPOUTS:
        return f"the rack-travel sensor's reading dropped out {x:.0f} time(s) (a contact: limit {limit:.0f})"
    if s is Signature.SENSOR_SPIKES:
        return f"the rack-travel sensor's reading spiked {x:.0f} times (limit {limit:.0f})"
    if s is Signature.SENSOR_NOISE:
        return f"the rack-travel sensor's reading is {x:.1f}x as noisy as its stated noise (limit {limit:g}x)"
    if s is Signature.SENSOR_ZERO:
        return f"the rack-travel sensor reads the rack at rest on its stop at {x:+.3f} mm (limit +/-{limit:g} mm)"
    if s is Signature.SENSOR_GAIN:
        return (f"the rack-travel sensor reads {x:+.1%} of the rack's travel: a2 and a0 moved together against the "
                f"new-valve baseline (limit +/-{limit:.0%})")
    if s is Signature.SENSOR_LINEARITY:
        return (f"the rack-travel sensor reads {x:+.2f} mm off in the swing but not at rest (the preload term b "
                f"moved): a sensor that is not linear, or a return spring whose preload differs (limit "
                f"+/-{limit:.2g} mm)")
    if s is Signature.SENSOR_UNEVEN:
        at = "" if finding.at_mm is None else f" near {finding.at_mm:.1f} mm"
        return (f"the rack-travel sensor reads {x:+.2f} mm off a straight line{at}, alike in both directions of "
                f"travel: more than the friction's rise there makes of a rack that binds (+/-{limit:.2g} mm): a "
                f"sensor that reads unevenly over part of its travel")
    if s is Signature.SPRING_RATE:
        return (f"the spring rate a0 differs {x:+.1%} from the new-valve baseline's (the rack's mass did not: the "
                "spring)")
    if s is Signature.RACK_BIND:
        at = "" if finding.at_mm is None else f" near {finding.at_mm:.1f} mm"
        return (f"the rack's friction rises{at} by {x:.0%} of a new valve's friction above the rest of the stroke "
                f"(limit {limit:.0%})")
    if s is Signature.RACK_SLOPE:
        return (f"the rack's friction changes by {x:+.0%} of a new valve's friction along the swing (limit "
                f"+/-{limit:.0%})")
    return (f"friction {x:+.0%} above a new valve's, the same along the whole stroke: a worn valve or a rack that "
            f"drags evenly (this test cannot tell them apart)")


#: What the technician does about each signature beyond its limit, the first that applies deciding.
_ACTIONS: tuple[tuple[Signature, str], ...] = (
    (Signature.SENSOR_DROPOUTS, "the rack-travel sensor's reading drops out: check its connector and cable, then "
                                "retest the valve"),
    (Signature.SENSOR_SPIKES, "the rack-travel sensor's reading spikes: check its cable and screening, then retest "
                              "the valve"),
    (Signature.SENSOR_NOISE, "the rack-travel sensor's reading is noisy: check or replace the sensor, then retest "
                             "the valve"),
    (Signature.SENSOR_ZERO, "the rack-travel sensor's zero is off: calibrate or replace the sensor, then retest the "
                            "valve"),
    (Signature.SENSOR_GAIN, "the rack-travel sensor is out of calibration (its scale): calibrate or replace the "
                            "sensor, then retest the valve"),
    (Signature.SENSOR_LINEARITY, "the rack-travel sensor is not linear, or the return spring's preload differs: "
                                 "check the sensor over a reference travel, then retest the valve"),
    (Signature.SENSOR_UNEVEN, "the rack-travel sensor reads unevenly over part of its travel: check it over a "
                              "reference travel (if it reads true, the rack binds there: free it), then retest the "
                              "valve"),
    (Signature.RACK_BIND, "the rack binds at one place: free or repair the rack (if it moves freely by hand, the "
                          "rack-travel sensor may read unevenly there: check it over a reference travel), then "
                          "retest the valve"),
    (Signature.RACK_SLOPE, "the rack's friction changes along its stroke: free or repair the rack, then retest the "
                           "valve"),
)


def part_words(diagnosis: PartDiagnosis) -> str:
    """What to do about a rack or sensor at fault (the technician's line after ``not judged: ``); empty for none."""
    beyond = {f.signature for f in diagnosis.beyond}
    for signature, words in _ACTIONS:
        if signature in beyond:
            return words
    return ""


#: The check for friction that is the same along the stroke: a worn valve and a rack that drags evenly read alike.
RACK_CHECK = "check by hand that the rack moves freely"


def part_line(diagnosis: PartDiagnosis | None) -> str:
    """The part at fault in a few words, for a screen's or a table's column (``valve only judged`` for none)."""
    if diagnosis is None:
        return str(Part.NOT_JUDGED)
    if diagnosis.part in (Part.SENSOR, Part.RACK):
        beyond = [f.signature for f in diagnosis.beyond if f.part is diagnosis.part]  # a sensor's: not the rack's too
        return f"{diagnosis.part}: {', '.join(str(s) for s in beyond)}"
    return str(diagnosis.part)


#: What page 1 tells the customer of each signature beyond its limit (no figure, no engineer's word).
_CUSTOMER: tuple[tuple[Signature, str], ...] = (
    (Signature.SENSOR_DROPOUTS, "The pump's rack-travel sensor lost its signal during the test (a bad contact)."),
    (Signature.SENSOR_SPIKES, "The pump's rack-travel sensor's signal was disturbed during the test."),
    (Signature.SENSOR_NOISE, "The pump's rack-travel sensor's signal is noisier than a sound sensor's."),
    (Signature.SENSOR_ZERO, "The pump's rack-travel sensor reads the rack's rest position wrongly."),
    (Signature.SENSOR_GAIN, "The pump's rack-travel sensor reads the rack's travel too long or too short."),
    (Signature.SENSOR_LINEARITY, "The pump's rack-travel sensor does not read the rack's travel evenly (or the "
                                 "rack's return spring is not as it should be)."),
    (Signature.SENSOR_UNEVEN, "The pump's rack-travel sensor reads part of the rack's travel unevenly."),
    (Signature.RACK_BIND, "The pump's control rack binds at one place along its travel."),
    (Signature.RACK_SLOPE, "The pump's control rack moves less freely at one end of its travel than at the other."),
)


def customer_words(diagnosis: PartDiagnosis | None) -> str:
    """Page 1's sentence on the part at fault (empty where none is: the valve's own findings say the rest)."""
    if diagnosis is None:
        return ""
    beyond = {f.signature for f in diagnosis.beyond}
    for signature, words in _CUSTOMER:
        if signature in beyond:
            return words
    if diagnosis.part is Part.VALVE_OR_RACK:
        return ("The friction is higher than a new valve's along the whole travel: a worn valve or a rack that drags "
                "evenly read alike, so the rack is checked by hand before the valve is replaced.")
    return ""


def finding_row(finding: PartFinding) -> tuple[str, str]:
    """One finding as page 2 lists it: its name, and its figure against its limit."""
    x = _figure(finding)
    if finding.unit == "mm":
        shown = f"{x:+.3f} mm (limit \u00b1{finding.limit:.3g} mm)"
    elif finding.unit == "x":
        shown = f"{x:.2f} \u00d7 stated (limit {finding.limit:g} \u00d7)"
    elif finding.signature in (Signature.SENSOR_DROPOUTS, Signature.SENSOR_SPIKES):
        shown = f"{x:.0f} (limit {finding.limit:.0f})"
    else:
        shown = f"{x * 100:+.1f} % (limit \u00b1{finding.limit * 100:.3g} %)"
    if finding.at_mm is not None:
        shown += f" at {finding.at_mm:.1f} mm"
    return str(finding.signature).capitalize(), shown + (" BEYOND" if finding.beyond else "")
