"""record.json is the serialisation of one model (records/schema.py's Record), built once by the writer: a field
declared there is written, read back, covered by the integrity manifest, read as its default from an older
record and indexed (history --verify names it when changed), with no other file edited. The report shows what
records/report_content.py places on its pages: a new figure appears there when it is placed (docs/bench-test.md
says why)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest
from pydantic import create_model

from edc_bench.bench import run_simulated_test
from edc_bench.config import load_variant, parse_variant
from edc_bench.engine.tick_timing import TickTiming
from edc_bench.errors import ConfigError
from edc_bench.records import reader, record
from edc_bench.records.reader import load_record
from edc_bench.records.record import build_record, record_json, write_record
from edc_bench.records.schema import Record, RecordFiles
from edc_bench.records.writer import RECORD_FILE


@pytest.fixture(scope="module")
def result():
    data = load_variant().model_dump()
    data["excitation"]["duration_s"] = 8.0
    return run_simulated_test(parse_variant(data), "worn", 2, check_gains=False)


def with_field(monkeypatch: pytest.MonkeyPatch) -> type[Record]:
    """Record with one more field, as if declared in records/schema.py (the modules that name Record see it)."""
    extended = create_model("Record", __base__=Record, bench_humidity_pct=(float | None, 41.5))
    monkeypatch.setattr(record, "Record", extended)
    monkeypatch.setattr(reader, "Record", extended)
    return extended


def test_a_field_added_to_the_model_is_written_read_back_and_covered_by_the_manifest(
        result, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    with_field(monkeypatch)
    folder = write_record(result, tmp_path, figure=False)
    doc = json.loads((folder / RECORD_FILE).read_text())
    assert doc["bench_humidity_pct"] == 41.5
    assert "bench_humidity_pct" in doc["integrity"]["sections"]
    assert load_record(folder).bench_humidity_pct == 41.5
    doc["bench_humidity_pct"] = 90.0  # changed after the test: refused, naming the field
    (folder / RECORD_FILE).write_text(json.dumps(doc))
    with pytest.raises(ConfigError, match="bench_humidity_pct"):
        load_record(folder)


def test_a_record_written_before_the_field_existed_reads_with_its_default(
        result, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    folder = write_record(result, tmp_path, figure=False)  # today's model
    assert "bench_humidity_pct" not in json.loads((folder / RECORD_FILE).read_text())
    with_field(monkeypatch)
    assert load_record(folder).bench_humidity_pct == 41.5


def test_record_json_is_the_models_serialisation_and_reads_back_equal(result, tmp_path: Path) -> None:
    """What is written is the built model, and reading it gives the model back (NaN figures aside: JSON holds
    them as null)."""
    folder = write_record(result, tmp_path, figure=False)
    written = json.loads((folder / RECORD_FILE).read_text())
    read = load_record(folder)
    built = build_record(result, read.files)
    assert {key: value for key, value in written.items() if key != "integrity"} == record_json(built)
    assert record_json(read) == record_json(built)
    assert isinstance(read.timing, TickTiming) and read.timing.ticks == result.timing.ticks > 0
    assert "retested_by" not in written  # declared for reading only


def test_a_section_that_does_not_fit_its_model_is_not_written(result, tmp_path: Path) -> None:
    """A bug that hands the writer a wrong figure fails at build time, before any record.json exists."""
    from dataclasses import replace

    from pydantic import ValidationError

    wrong = replace(result, identity={"station": ["not", "a", "name"]})
    with pytest.raises(ValidationError, match="Identity\nstation"):
        build_record(wrong, RecordFiles())
    with pytest.raises(ValidationError):
        write_record(wrong, tmp_path, figure=False)
    (folder,) = tmp_path.iterdir()
    assert not (folder / RECORD_FILE).exists() and (folder / "can.log").stat().st_size > 0  # the data kept


def test_a_stop_reason_read_back_is_the_enum_and_an_unknown_one_is_kept_as_text() -> None:
    from edc_bench.engine.outcome import StopReason
    from edc_bench.records.schema import StopSummary

    assert StopSummary.model_validate({"reason": "verdict certain"}).reason is StopReason.VERDICT_CERTAIN
    assert StopSummary.model_validate({"reason": "a newer reason"}).reason == "a newer reason"


def test_a_timing_holding_null_counts_reads_as_none_counted(result, tmp_path: Path) -> None:
    """A damaged record's null counts were read as 0 when timing was a mapping: still read, not refused."""
    folder = write_record(result, tmp_path, figure=False)
    doc = json.loads((folder / RECORD_FILE).read_text())
    doc["timing"].update(ticks=None, ticks_late=None, missed_replies=None, cpu_steal_s=None)
    timing = reader.typed_record(reader.upgraded(doc), folder).timing
    assert (timing.ticks, timing.ticks_late, timing.missed_replies, timing.cpu_steal_s) == (0, 0, 0, 0.0)


def test_the_loop_section_holds_the_engines_abort_and_refuses_one_that_is_not(result, tmp_path: Path) -> None:
    """record.json's loop.abort is the engine's Abort (kind and typed figures) written and read back; a hand-edited
    one that is no abort is refused naming the field, and an older record's loop.stop (now only in the record's
    stop section) is kept as an unknown key."""
    from edc_bench.engine.abort_figures import SilenceFigures
    from edc_bench.engine.outcome import Abort, AbortKind

    abort = Abort(AbortKind.SILENCE, SilenceFigures(in_row=12, limit=10, bad_replies=2), 3.25)
    folder = write_record(replace_outcome(result, abort=abort), tmp_path, figure=False)
    doc = json.loads((folder / RECORD_FILE).read_text())
    assert "stop" not in doc["loop"] and doc["stop"]["reason"]
    assert doc["loop"]["abort"] == {"kind": "rig silent", "figures": abort.figures.as_dict(), "time_s": 3.25}
    read = load_record(folder)
    assert read.loop.abort == abort and read.loop.abort.figures.in_row == 12
    # each refused in one line naming the field and what is wrong (words the hand-edited value does not hold)
    for hostile, words in (("a string", "is a mapping with its"), ({"figures": {}}, "names its 'kind'"),
                           ({"kind": "rig silent", "time_s": "x"}, "is a number of seconds"),
                           ({"kind": "rig silent", "time_s": 10**400}, "is a number of seconds"),
                           ({"kind": "rig silent", "figures": "abc"}, "each figure by its name"),
                           ({"kind": "rig silent", "figures": [1, 2]}, "each figure by its name"),
                           ({"kind": ["a list"]}, "not a valid AbortKind"),
                           ({"kind": "no such kind"}, "not a valid AbortKind")):
        edited = {**doc, "loop": {**doc["loop"], "abort": hostile}}
        with pytest.raises(ConfigError, match=rf"(?s)loop\.abort.*{words}"):
            reader.typed_record(reader.upgraded(edited), folder)
    # a figure a hand edit made unreadable (too large for a float) takes its default, as a missing one does
    huge = {"kind": "slow link", "figures": {"max_reply_age_ms": 10**400, "in_row": 7}, "time_s": 2}
    abort = reader.typed_record(reader.upgraded({**doc, "loop": {**doc["loop"], "abort": huge}}), folder).loop.abort
    assert math.isnan(abort.figures.max_reply_age_ms) and abort.figures.in_row == 7 and abort.time_s == 2.0
    older = {**doc, "loop": {**doc["loop"], "stop": {"reason": "full length", "time_s": 30.0}}}
    assert reader.typed_record(reader.upgraded(older), folder).loop.model_extra["stop"]["time_s"] == 30.0


def replace_outcome(result, **changes):
    """``result`` with its loop outcome changed (a frozen result: a copy)."""
    from dataclasses import replace

    return replace(result, outcome=replace(result.outcome, **changes))


def test_a_field_added_to_the_model_is_indexed_and_verify_names_it_when_changed(
        result, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The history keeps the record's digest and manifest: a new field, changed after indexing, is named."""
    from edc_bench.history.store import HistoryStore, index_record_dir
    from edc_bench.history.verify import verify

    with_field(monkeypatch)
    folder = write_record(result, tmp_path / "records", figure=False)
    url = f"sqlite:///{tmp_path / 'history.sqlite'}"
    index_record_dir(folder, url)
    with HistoryStore(url) as store:
        rows = store.indexed()
    assert len(rows) == 1 and verify(rows) == []
    doc = json.loads((folder / RECORD_FILE).read_text())
    doc["bench_humidity_pct"] = 90.0
    (folder / RECORD_FILE).write_text(json.dumps(doc))
    (finding,) = verify(rows)
    assert finding.problem == "altered" and "'bench_humidity_pct'" in finding.detail, finding


def test_a_loop_figure_the_summary_does_not_declare_is_kept_and_named() -> None:
    """LoopSummary.of passes every figure of the outcome: one added there without being declared in the summary
    is kept as an extra (written, and named by the writer's check of undeclared keys), never dropped."""
    from dataclasses import dataclass

    from edc_bench.engine.loop_summary import LoopSummary
    from edc_bench.engine.outcome import LoopOutcome
    from edc_bench.records.schema import undeclared_keys

    @dataclass
    class Newer(LoopOutcome):
        bus_load_pct: float = 42.0

    summary = LoopSummary.of(Newer(ticks_planned=10))
    assert summary.model_extra == {"bus_load_pct": 42.0}
    assert "loop.bus_load_pct" in undeclared_keys(Record(verdict="PASS", loop=summary))
