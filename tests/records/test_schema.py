"""The typed record: one reader for the report, the history, replay and classify, and a schema the writer keeps to."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from helpers import edc_bench, rewrite_record_json

from edc_bench.bench import BenchOptions, run_bench_test, run_simulated_test
from edc_bench.config import load_variant, parse_variant
from edc_bench.errors import ConfigError
from edc_bench.records.reader import load_record
from edc_bench.records.record import write_record
from edc_bench.records.schema import Record, undeclared_keys
from edc_bench.testing.faults import FaultyBus, Rule
from edc_bench.verdict.verdicts import Verdict


@pytest.fixture(scope="module")
def records(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """A record folder of each kind the bench writes: judged, aborted, not judged, the model not fitting."""
    from conftest import simulated_bench_factory

    out = tmp_path_factory.mktemp("kinds")
    short = load_variant().model_dump()
    short["excitation"]["duration_s"] = 8.0
    short_variant = parse_variant(short)
    renamed = load_variant().model_dump()
    renamed["pump"]["name"] = "a-pump-not-calibrated"
    uncalibrated = parse_variant(renamed)
    folders = {"judged": write_record(run_simulated_test(load_variant(), "worn", 2), out, figure=False),
               "unclassified": write_record(run_simulated_test(load_variant(), "new", 1, classify=False), out,
                                            figure=False),
               # features so far beyond the boundary that the classifier's scan (3.0) finds none: distance inf, which
               # JSON holds as null (the soak's 1,500 tests found 10 such valves, their records unreadable then)
               "beyond the scan": write_record(run_simulated_test(load_variant(), "clearance=0.5,roughness=2", 2),
                                               out, figure=False),
               "nominal": write_record(run_simulated_test(uncalibrated, "new", 1, nominal_baseline=True,
                                                          coil_temp_c=35.0), out, figure=False)}
    with simulated_bench_factory() as make:
        bench, clock, _ = make(short_variant, "new", 3)
        aborted = run_bench_test(FaultyBus(bench, clock.now_s, [Rule("cut", 2.5)]), clock, short_variant,
                                 BenchOptions(check_gains=False))
    folders["aborted"] = write_record(aborted, out, figure=False)
    data = load_variant("p-edc-hard").model_dump()
    data["coil"]["force_constant_variation_per_mm"] = 0.0667  # +/-30 % over the swing: the model cannot fit
    data["pump"]["name"] = "gain-test"
    folders["model does not fit"] = write_record(
        run_simulated_test(parse_variant(data), "worn", 0, nominal_baseline=True), out, figure=False)
    return folders


def test_every_kind_of_record_reads_typed_and_the_schema_declares_all_it_holds(records: dict[str, Path]) -> None:
    """The writer writes nothing the schema does not declare, for every kind of record; the reader types it."""
    kinds = {}
    for kind, folder in records.items():
        record = load_record(folder)
        assert isinstance(record, Record)
        assert undeclared_keys(record) == [], kind
        kinds[kind] = record
    judged = kinds["judged"]
    assert judged.verdict in (Verdict.PASS, Verdict.MARGINAL, Verdict.FAIL)
    assert judged.classification is not None and judged.classification.probability_faulty >= 0.0
    assert judged.decision_plane is not None and judged.parameters["af"].estimated
    assert kinds["unclassified"].verdict == Verdict.UNCLASSIFIED and kinds["unclassified"].classification is None
    assert kinds["nominal"].baseline is not None and kinds["nominal"].baseline.calibrated is False
    assert kinds["nominal"].coil is not None and kinds["nominal"].coil.temp_given
    aborted = kinds["aborted"]
    assert aborted.verdict == Verdict.INVALID and aborted.loop.abort is not None
    assert aborted.loop.abort_reason and aborted.loop.ticks_run < (aborted.loop.ticks_planned or 0)
    far = kinds["beyond the scan"]
    assert far.verdict == Verdict.FAIL and far.classification is not None and far.classification.distance is None
    from edc_bench.history.store import row_from_record
    from edc_bench.records.report_content import classifier_rows

    assert "beyond the classifier's scan" in dict(classifier_rows(far))["Distance"]
    assert row_from_record(far, records["beyond the scan"])["distance"] is None
    fit = kinds["model does not fit"].identification
    assert fit is not None and fit.model_fit is not None and fit.model_fit.fits is False
    with pytest.raises(Exception, match="frozen"):
        judged.verdict = Verdict.PASS  # a record read is not changed by its readers


def test_an_undeclared_key_is_found(records: dict[str, Path], tmp_path: Path) -> None:
    """The schema check can fail: a key the writer added without declaring it is named with its path."""
    doc = json.loads((records["judged"] / "record.json").read_text(encoding="utf-8"))
    doc["classification"]["new_figure"] = 1.0
    doc["extra_section"] = {}
    record = Record.model_validate(doc)
    assert undeclared_keys(record) == ["extra_section", "classification.new_figure"]


@pytest.mark.parametrize("argv", [("report", "rec"), ("history", "--add", "rec", "--db", "sqlite:///h.sqlite"),
                                  ("classify", "rec"), ("replay", "rec")])
def test_a_hand_edited_field_is_refused_by_every_reader_in_one_line(records: dict[str, Path], tmp_path: Path,
                                                                     argv: tuple[str, ...]) -> None:
    """One reader: a field of the wrong type is named, with what it holds, whichever command reads the record."""
    import shutil

    folder = tmp_path / "rec"
    shutil.copytree(records["judged"], folder)
    doc = json.loads((folder / "record.json").read_text(encoding="utf-8"))
    doc["classification"]["probability_faulty"] = "high"
    rewrite_record_json(folder, doc)  # as another writer would have written it, manifest and all
    proc = edc_bench(*argv, cwd=tmp_path)
    assert proc.returncode == 2, proc.stderr
    assert "classification.probability_faulty holds 'high'" in proc.stderr and "Traceback" not in proc.stderr
    assert len(proc.stderr.strip().splitlines()) == 1


def test_a_record_of_a_newer_edc_bench_is_read(records: dict[str, Path], tmp_path: Path) -> None:
    """Keys a newer edc-bench adds are kept, not refused, and the record reads as before."""
    import shutil

    folder = tmp_path / "newer"
    shutil.copytree(records["judged"], folder)
    doc = json.loads((folder / "record.json").read_text(encoding="utf-8"))
    doc["schema"] = 99
    doc["coil"]["inductance_measured_mh"] = 1.1
    rewrite_record_json(folder, doc)
    record = load_record(folder)
    assert record.schema_version == 99 and record.coil is not None
    assert record.coil.model_extra == {"inductance_measured_mh": 1.1}


def test_a_record_needs_a_verdict_it_knows(tmp_path: Path) -> None:
    (tmp_path / "record.json").write_text('{"verdict": "GOOD"}', encoding="utf-8")
    with pytest.raises(ConfigError, match=r"verdict holds 'GOOD'.*'PASS'"):
        load_record(tmp_path)


def test_a_retests_decision_is_a_verdict_and_an_older_empty_one_is_none(tmp_path: Path) -> None:
    """#54: the retest's decision, the verdicts it pairs and an escalation's cause are values, not free text: a
    record's "" (older records wrote it for none) reads as None, a word that is no verdict is refused naming it."""
    from edc_bench.records.advice import Cause
    from edc_bench.records.reader import typed_record

    base = {"verdict": "FAIL", "retest": {"of_record": "a", "of_verdict": "MARGINAL", "decision": "FAIL"},
            "escalation": {"of_record": "b", "of_verdict": "INVALID", "of_cause": "valve"}}
    record = typed_record(base, tmp_path)
    assert record.retest.decision is Verdict.FAIL and record.retest.of_verdict is Verdict.MARGINAL
    assert record.escalation.of_cause is Cause.VALVE
    assert typed_record({**base, "retest": {"of_record": "a", "decision": ""}}, tmp_path).retest.decision is None
    with pytest.raises(ConfigError, match=r"retest.decision holds 'FAIL, probably'"):
        typed_record({**base, "retest": {"decision": "FAIL, probably"}}, tmp_path)


def test_a_neighbours_damaged_retest_does_not_stop_the_first_tests_report(tmp_path: Path) -> None:
    """The first test's report looks beside it for its retest; a retest whose decision is no verdict (a damaged
    record) is named without one, never a validation error."""
    from edc_bench.records.retest_link import find_retest

    first = tmp_path / "20261128T100000+0000-p-edc-default-V1"
    second = tmp_path / "20261128T100100+0000-p-edc-default-V1"
    for folder in (first, second):
        folder.mkdir()
    (second / "record.json").write_text(json.dumps({"verdict": "PASS", "retest": {
        "of_record": first.name, "decision": None, "words": "w"}}), encoding="utf-8")
    record = Record.model_validate({"verdict": "MARGINAL", "variant": "p-edc-default"})
    found = find_retest(first, record)
    assert found is not None and found.verdict is Verdict.PASS and found.decision is None
