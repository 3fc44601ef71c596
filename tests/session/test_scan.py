"""The prompts' fixed order, and what a scanned line does at each (edc_bench.session.scan)."""

from __future__ import annotations

from edc_bench.session.scan import Scan, Step, part_number_index, read_line

PARTS = {"PE-EDC-0001": "p-edc-default", "PE-EDC-0002": "p-edc-long"}


def test_valve_id_then_pump_serial_then_mount_always_in_that_order() -> None:
    scan = Scan(variant="p-edc-default")
    steps = []
    for line in ("V-1001", "PS-77", ""):
        answer = read_line(scan, line, PARTS)
        scan = answer.scan
        steps.append((scan.step, answer.start_test))
    assert steps == [(Step.PUMP_SERIAL, False), (Step.MOUNT, False), (Step.VALVE_ID, True)]
    assert (scan.valve_id, scan.pump_serial) == ("V-1001", "PS-77")


def test_a_part_number_at_any_prompt_switches_the_pump_type_and_keeps_the_prompt() -> None:
    for step in Step:
        scan = Scan(step=step, valve_id="V-1", pump_serial="PS-1", variant="p-edc-default")
        answer = read_line(scan, " PE-EDC-0002 ", PARTS)
        assert answer.switched_variant and answer.scan.variant == "p-edc-long"
        assert answer.scan.step is step and not answer.start_test


def test_an_empty_id_or_text_at_mount_is_refused_with_what_to_do() -> None:
    empty = read_line(Scan(), "  ", PARTS)
    assert empty.refused and "valve id is empty" in empty.message and empty.scan.step is Step.VALVE_ID
    stray = read_line(Scan(step=Step.MOUNT, valve_id="V", pump_serial="P"), "V-2", PARTS)
    assert stray.refused and not stray.start_test and "press Enter alone" in stray.message
    long = read_line(Scan(), "x" * 101, PARTS)
    assert long.refused and "at most 100" in long.message


def test_a_part_number_two_variants_share_switches_to_neither() -> None:
    assert part_number_index({"a": "P1", "b": "P1", "c": "P2"}) == {"P2": "c"}
