"""The smaller traps a new user met (#52): an empty valve id, a valve id in another script, a watchdog shorter than
the loop, a simulated test's customer page."""

from __future__ import annotations

from pathlib import Path

import pytest
from pydantic import ValidationError

from edc_bench.cli import main
from edc_bench.config import load_variant
from edc_bench.records.report_content import test_rows as who_and_when_rows
from edc_bench.records.schema import Record
from edc_bench.records.writer import new_record_dir


@pytest.mark.parametrize("flag", ["--valve-id", "--pump-serial"])
def test_an_empty_id_is_refused_like_a_blank_one(flag: str, capsys: pytest.CaptureFixture[str]) -> None:
    for given in ("", "   "):
        with pytest.raises(SystemExit) as exit_:
            main(["test", flag, given])
        err = capsys.readouterr().err
        assert exit_.value.code == 2 and f"argument {flag}" in err and len(err.strip().splitlines()) == 1, err


def test_a_valve_id_in_another_script_keeps_its_letters_in_the_folder_name(tmp_path: Path) -> None:
    for valve, shown in (("Ölventil", "Ölventil"), ("V-2040", "V-2040"), ("a/b c", "a_b_c"), ("..", "valve"),
                         ("日本-7", "日本-7"), ("V;DROP TABLE--ä€", "V_DROP_TABLE--ä")):
        folder = new_record_dir(tmp_path, valve, "p-edc-default", "2026-11-27T10:00:00+00:00")
        assert folder.name == f"20261127T100000+0000-p-edc-default-{shown}", valve
        assert folder.parent == tmp_path


def test_a_watchdog_that_does_not_outlast_two_ticks_is_refused() -> None:
    variant = load_variant()
    data = variant.model_dump()
    data["rig"]["watchdog_ms"] = 1.5  # the loop's period is 1 ms
    with pytest.raises(ValidationError, match="does not outlast two ticks of the loop"):
        type(variant).model_validate(data)
    data["rig"]["watchdog_ms"] = 20.0
    type(variant).model_validate(data)


def test_a_simulated_tests_customer_page_says_no_real_valve_was_tested() -> None:
    simulated = Record.model_validate({"verdict": "PASS", "clock": "simulated", "simulation": {"valve": {"label": "new"}}})
    rows = dict(who_and_when_rows(simulated))
    assert rows.get("Rig") == "SIMULATED: no real valve was tested", rows
    on_a_rig = Record.model_validate({"verdict": "PASS", "clock": "real-time"})
    assert "Rig" not in dict(who_and_when_rows(on_a_rig))


def test_a_hand_edited_can_log_is_blamed_not_the_tests_own_variant(tmp_path: Path) -> None:
    from edc_bench.bench import run_simulated_test
    from edc_bench.errors import ConfigError
    from edc_bench.records.record import write_record
    from edc_bench.replay import replay_record

    folder = write_record(run_simulated_test(load_variant(), "new", 2), tmp_path, figure=False)
    log = folder / "can.log"
    lines = log.read_text().splitlines()
    k = next(i for i in range(len(lines) // 2, len(lines)) if " 121#" in lines[i])  # a rig feedback mid-test
    head, data = lines[k].rsplit("#", 1)
    lines[k] = f"{head}#{data[:2]}{'0' if data[2] != '0' else '1'}{data[3:]}"  # one hex digit of its position
    log.write_text("\n".join(lines) + "\n")
    with pytest.raises(ConfigError, match="the CAN log is not the one the test wrote") as refused:
        replay_record(folder)
    assert "this variant" not in str(refused.value)


def test_a_quick_perf_run_judges_no_target() -> None:
    from edc_bench.cli.perf_cmd import unjudged
    from edc_bench.perf.figures import Figure

    figures = [Figure("loop", "p99 lateness", 250.0, "us", target="< 300 us", met=True),
               Figure("speed", "simulated test", 20.0, "x real time", target=">= 50x", met=False, note="2 tests"),
               Figure("speed", "batch", 900.0, "tests/min")]
    shown = unjudged(figures)
    assert [f.met for f in shown] == [None, None, None]
    assert shown[1].note == "2 tests; target not judged: a quick run is too short for it" and shown[2].note == ""
    assert [f.target for f in shown] == [f.target for f in figures]  # the target still said, not judged
