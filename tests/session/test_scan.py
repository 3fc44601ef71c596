"""The prompts' fixed order, and what a scanned line does at each (edc_bench.session.scan)."""

from __future__ import annotations

import pytest

from edc_bench.errors import ConfigError
from edc_bench.session.scan import Scan, ScanContext, Step, part_number_index, read_line
from edc_bench.session.scan_rules import scan_rules

PARTS = ScanContext({"PE-EDC-0001": "p-edc-default", "PE-EDC-0002": "p-edc-long"})


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


def _scan_twice(scan: Scan, line: str, context: ScanContext) -> tuple[str, Scan]:
    """The first answer's message (asked about), and the state after the same line scanned again."""
    first = read_line(scan, line, context)
    assert first.refused and first.scan.step is scan.step and first.scan.pending == line
    second = read_line(first.scan, line, context)
    assert not second.refused and second.scan.pending == ""
    return first.message, second.scan


def test_a_double_scan_of_the_valve_label_is_asked_about_and_taken_only_when_scanned_again() -> None:
    scan = read_line(Scan(), "V-1001", PARTS).scan
    message, after = _scan_twice(scan, "V-1001", PARTS)
    assert "the pump serial 'V-1001' is the valve id again" in message and "scan it again to take it" in message
    assert (after.step, after.pump_serial) == (Step.MOUNT, "V-1001")
    # another line in between: the first is forgotten, the right serial taken at once
    asked = read_line(scan, "V-1001", PARTS).scan
    right = read_line(asked, "PS-77", PARTS)
    assert not right.refused and right.scan.pump_serial == "PS-77"
    assert read_line(read_line(right.scan, "", PARTS).scan, "V-1001", PARTS).scan.step is Step.PUMP_SERIAL


def test_an_id_with_characters_no_label_has_is_asked_about_naming_them() -> None:
    message, after = _scan_twice(Scan(), "v@l#ve;DROP TABLE--ä€", PARTS)
    assert "characters an id rarely has ('@' '#' ';' space 'ä' '€')" in message
    assert after.valve_id == "v@l#ve;DROP TABLE--ä€"  # taken as it is when confirmed: stored as data, never SQL
    for plain in ("V-9999", "clearance=0.185", "2024/17.3"):
        assert read_line(Scan(), plain, PARTS).scan.step is Step.PUMP_SERIAL, plain
    # what a scanner set to a German keyboard types for "-", full-width and Arabic-Indic digits: asked about
    for odd, named in (("Vß12345", "'ß'"), ("V１２３", "'１' '２' '３'"), ("V-١٢٣", "'١' '٢' '٣'")):
        assert f"characters an id rarely has ({named})" in read_line(Scan(), odd, PARTS).message, odd


def test_a_valve_judged_in_this_shift_is_asked_about_naming_its_verdict() -> None:
    context = ScanContext(PARTS.part_numbers, judged={"V-7": "FAIL at 10:02"})
    message, after = _scan_twice(Scan(), "V-7", context)
    assert "valve V-7 was judged in this shift already (FAIL at 10:02)" in message
    assert after.valve_id == "V-7"


def test_the_stations_patterns_ask_about_misfits_and_refuse_unknown_part_numbers() -> None:
    rules = scan_rules({"valve_id": r"V-\d{5}", "pump_serial": r"PS-\d{4}", "part_number": r"PE-EDC-\d{4}"},
                       "station.toml")
    context = ScanContext(PARTS.part_numbers, rules)
    assert read_line(Scan(), "V-12345", context).scan.step is Step.PUMP_SERIAL
    message, _ = _scan_twice(Scan(), "V-9999faulty", context)
    assert "'V-9999faulty' does not look like a valve id here (the station's pattern V-\\d{5})" in message
    assert "does not look like" in read_line(Scan(), "V-١٢٣٤٥", context).message  # \d is 0-9 only
    unknown = read_line(Scan(), "PE-EDC-0099", context)
    assert unknown.refused and "part number of no pump type" in unknown.message and unknown.scan.pending == ""
    assert read_line(Scan(), "PE-EDC-0002", context).switched_variant


def test_a_job_reference_scanned_at_any_prompt_is_noted_for_the_valve_and_keeps_the_prompt() -> None:
    """#53 item 8: the job or vehicle reference, scanned with the valve, reaches the customer's page. A line that
    fits the shop's ``[scan] job`` pattern is it, at any prompt; without a pattern no line is one."""
    rules = scan_rules({"job": r"JOB-\d{6}"}, "station.toml")
    context = ScanContext(PARTS.part_numbers, rules)
    for scan in (Scan(), Scan(step=Step.PUMP_SERIAL, valve_id="V-1"),
                 Scan(step=Step.MOUNT, valve_id="V-1", pump_serial="PS-1")):
        answer = read_line(scan, "JOB-004711", context)
        assert answer.noted and not answer.refused and not answer.start_test
        assert answer.scan == Scan(step=scan.step, valve_id=scan.valve_id, pump_serial=scan.pump_serial,
                                   job_ref="JOB-004711")
        assert answer.message == "job or vehicle reference JOB-004711 noted for this valve"
    kept = read_line(read_line(Scan(job_ref="JOB-004711"), "V-1", context).scan, "PS-1", context).scan
    assert kept.job_ref == "JOB-004711" and kept.step is Step.MOUNT
    assert read_line(kept, "", context).start_test
    unset = read_line(Scan(), "JOB-004711", ScanContext(PARTS.part_numbers, scan_rules({}, "station.toml")))
    assert not unset.noted and unset.scan.valve_id == "JOB-004711"  # no pattern: an id like any other


@pytest.mark.parametrize(("section", "words"), [
    ({"valve": "V"}, "[scan] valve is not a field; the fields are valve_id, pump_serial, part_number, job"),
    ({"valve_id": "V-("}, "is not a regular expression"),
    ({"valve_id": 5}, "give a regular expression as a string"),
])
def test_a_bad_scan_setting_is_refused_naming_it(section: dict, words: str) -> None:
    with pytest.raises(ConfigError, match="station.toml") as caught:
        scan_rules(section, "station.toml")
    assert words in str(caught.value)


def test_the_docs_scan_settings_work_as_written_and_a_bad_file_stops_the_session_naming_it(
        tmp_path, monkeypatch: pytest.MonkeyPatch) -> None:
    import re

    from helpers import REPO

    from edc_bench.session.build import make_app
    from edc_bench.session.runner import RigChoice
    from edc_bench.session.scan_rules import station_scan_rules
    from edc_bench.station_settings import SETTINGS_FILE

    (example,) = [block for block in re.findall(r"```toml\n(.*?)```", (REPO / "docs/station.md").read_text(),
                                                re.S) if "[scan]" in block]
    monkeypatch.setenv("EDC_BENCH_DATA_DIR", str(tmp_path))
    (tmp_path / SETTINGS_FILE).write_text(example, encoding="utf-8")
    context = ScanContext(PARTS.part_numbers, station_scan_rules())
    assert read_line(Scan(), "V-20417", context).scan.step is Step.PUMP_SERIAL
    assert "does not look like a valve id here" in read_line(Scan(), "V-9999faulty", context).message
    (tmp_path / SETTINGS_FILE).write_text("[scan]\nvalve_id = 'V-('\n", encoding="utf-8")
    with pytest.raises(ConfigError, match=f"{SETTINGS_FILE}: \\[scan\\] valve_id = 'V-\\(' is not a regular"):
        make_app(None, RigChoice(), tmp_path / "records", f"sqlite:///{tmp_path / 'h.sqlite'}", "b", "Jo")


def test_a_valve_left_invalid_is_not_asked_about_when_scanned_again() -> None:
    from edc_bench.session.shift import ShiftLog, ValveEntry

    shift = ShiftLog("Jo", "bench-1", "simulated rig")
    for valve, final in (("V-1", "FAIL"), ("V-2", "INVALID"), ("V-3", "PASS")):
        shift.valves.append(ValveEntry(valve, "PS", "p-edc-default", (final,), final, "", (), "2026-11-27T10:02:31"))
    assert shift.judged() == {"V-1": "FAIL at 10:02", "V-3": "PASS at 10:02"}
    context = ScanContext(PARTS.part_numbers, judged=shift.judged())
    assert read_line(Scan(), "V-2", context).scan.step is Step.PUMP_SERIAL  # INVALID: tested again, as told
    assert read_line(Scan(), "V-1", context).refused
