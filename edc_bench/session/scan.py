"""The prompts of a shift, always in one order, and what a line typed or scanned at them means.

A barcode scanner is a keyboard that types a line and Enter, so the order is fixed and every prompt ends with
Enter: the valve id, then the pump serial, then "mount the valve, then Enter". A pump part number of the variant
library, scanned at any prompt, switches the pump type instead of answering the prompt; a line that fits the shop's
job pattern (``[scan] job``), scanned at any prompt, is the job or vehicle reference of the valve being scanned (the
customer's page prints it), kept until that valve's test starts.

A line that may be a mistake is not taken at once: an id that does not fit the station's pattern
(:mod:`edc_bench.session.scan_rules`), a pump serial equal to the valve id (the same label scanned twice), a
valve already judged in this shift. The prompt stays, says why, and the same line scanned again takes it. Pure:
lines in, steps out.
"""

from __future__ import annotations

import enum
from collections.abc import Mapping
from dataclasses import dataclass, field, replace

from edc_bench.session.scan_rules import ScanRules

#: The longest identity kept (as ``edc-bench test --valve-id`` takes it).
MAX_ID_CHARS = 100


class Step(enum.Enum):
    """Where the shift is: which prompt is on screen."""

    VALVE_ID = "valve id"
    PUMP_SERIAL = "pump serial"
    MOUNT = "mount"


#: The words of each prompt.
PROMPTS = {
    Step.VALVE_ID: "Scan or type the VALVE ID, then Enter",
    Step.PUMP_SERIAL: "Scan or type the PUMP SERIAL, then Enter",
    Step.MOUNT: "Mount the valve on the rig, then press Enter to test it",
}


@dataclass(frozen=True)
class Scan:
    """The answers so far for the next valve, and the pump type the session tests."""

    step: Step = Step.VALVE_ID
    valve_id: str = ""
    pump_serial: str = ""
    variant: str = ""  # the variant's name
    job_ref: str = ""  # the job or vehicle reference scanned for this valve ("" if none)
    pending: str = ""  # a line asked about: scanned again, it is taken


@dataclass(frozen=True)
class Answer:
    """What a line did: the new state, what to say about it, and whether the valve is ready to test."""

    scan: Scan
    message: str = ""
    start_test: bool = False
    switched_variant: bool = False
    refused: bool = False
    noted: bool = False  # a job or vehicle reference: the prompt stays as it was


@dataclass(frozen=True)
class ScanContext:
    """What a line is checked against: the pump types' part numbers, the station's patterns, the valves judged in
    this shift (valve id -> what was decided, as said on screen)."""

    part_numbers: Mapping[str, str]
    rules: ScanRules = field(default_factory=ScanRules)
    judged: Mapping[str, str] = field(default_factory=dict)


def read_line(scan: Scan, line: str, context: ScanContext) -> Answer:
    """What ``line``, typed or scanned at the current prompt, does.

    Parameters
    ----------
    scan : Scan
        The state before the line.
    line : str
        The line as typed (without its Enter).
    context : ScanContext
        The part numbers, patterns and valves judged it is checked against.

    Returns
    -------
    Answer
    """
    text = line.strip()
    if text in context.part_numbers:
        variant = context.part_numbers[text]
        return Answer(replace(scan, variant=variant, pending=""),
                      f"pump type switched to {variant} (part number {text})", switched_variant=True)
    if len(text) <= MAX_ID_CHARS and text.isprintable() and context.rules.looks_like_job(text):
        return Answer(replace(scan, job_ref=text, pending=""), f"job or vehicle reference {text} noted for this valve",
                      noted=True)
    if scan.step is Step.MOUNT:
        if text:
            return Answer(scan, f"{text!r} is not a pump part number: mount the valve and press Enter alone "
                                "(Esc goes back to the valve id)", refused=True)
        return Answer(replace(scan, step=Step.VALVE_ID, pending=""), start_test=True)
    if not text:
        return Answer(replace(scan, pending=""), f"the {scan.step.value} is empty: scan or type it", refused=True)
    if len(text) > MAX_ID_CHARS or not text.isprintable():
        return Answer(replace(scan, pending=""), f"the {scan.step.value} must be at most {MAX_ID_CHARS} printable "
                                                 "characters", refused=True)
    if context.rules.looks_like_part_number(text):
        return Answer(replace(scan, pending=""), f"{text!r} is a part number of no pump type in the variant library: "
                                                 f"scan the {scan.step.value}, or add the pump type", refused=True)
    doubt = _doubt(scan, text, context)
    if doubt and scan.pending != text:
        return Answer(replace(scan, pending=text), f"{doubt}: scan it again to take it as it is, or scan the right "
                                                   f"{scan.step.value}", refused=True)
    if scan.step is Step.VALVE_ID:
        return Answer(replace(scan, step=Step.PUMP_SERIAL, valve_id=text, pump_serial="", pending=""))
    return Answer(replace(scan, step=Step.MOUNT, pump_serial=text, pending=""))


def _doubt(scan: Scan, text: str, context: ScanContext) -> str | None:
    """Why ``text`` may be a mistake at this prompt (None: it looks right)."""
    if scan.step is Step.VALVE_ID:
        reasons = [context.rules.misfit("valve_id", text)]
        if text in context.judged:
            reasons.append(f"valve {text} was judged in this shift already ({context.judged[text]})")
    else:
        reasons = [context.rules.misfit("pump_serial", text)]
        if text == scan.valve_id:
            reasons.append(f"the pump serial {text!r} is the valve id again (the same label scanned twice?)")
    found = [reason for reason in reasons if reason]
    return "; ".join(found) if found else None


def part_number_index(variants: Mapping[str, str]) -> dict[str, str]:
    """Part number -> variant name, from variant name -> part number (a part number used twice names neither)."""
    index: dict[str, str] = {}
    twice: set[str] = set()
    for name, part in variants.items():
        if part in index:
            twice.add(part)
        index[part] = name
    return {part: name for part, name in index.items() if part not in twice}
