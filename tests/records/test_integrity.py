"""A record changed after its test is refused by every reader, naming what changed; replay reports it."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from edc_bench.bench import run_simulated_test
from edc_bench.config import load_variant
from edc_bench.errors import ConfigError
from edc_bench.records.reader import load_record
from edc_bench.records.record import write_record
from helpers import edc_bench


@pytest.fixture(scope="module")
def written(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("records")
    return write_record(run_simulated_test(load_variant(), "new", 3), out, figure=True)


def copy(written: Path, tmp_path: Path) -> Path:
    folder = tmp_path / "rec"
    shutil.copytree(written, folder)
    return folder


def test_a_record_carries_the_digests_of_what_its_test_wrote(written: Path) -> None:
    record = load_record(written)
    assert record.integrity is not None
    assert set(record.integrity["files"]) == {"trace.mf4", "can.log", "report.png"}
    assert {"verdict", "parameters", "loop", "schema"} <= set(record.integrity["sections"])


@pytest.mark.parametrize("argv", [("report", "rec"), ("classify", "rec"), ("history", "--add", "rec")])
def test_a_verdict_edited_from_pass_to_fail_is_refused_naming_it(written: Path, tmp_path: Path,
                                                               argv: tuple[str, ...]) -> None:
    folder = copy(written, tmp_path)
    doc = json.loads((folder / "record.json").read_text())
    assert doc["verdict"] == "PASS"
    doc["verdict"] = "FAIL"
    (folder / "record.json").write_text(json.dumps(doc, indent=2))
    proc = edc_bench(*argv, cwd=tmp_path)
    assert proc.returncode == 2, proc.stdout + proc.stderr
    assert "changed after its test wrote it (record.json's 'verdict')" in proc.stderr
    assert len(proc.stderr.strip().splitlines()) == 1 and "Traceback" not in proc.stderr
    assert not (folder / "report.pdf").exists()  # nothing drawn from it


def test_replay_says_the_record_changed(written: Path, tmp_path: Path) -> None:
    folder = copy(written, tmp_path)
    doc = json.loads((folder / "record.json").read_text())
    doc["operator"] = "someone else"
    (folder / "record.json").write_text(json.dumps(doc))
    proc = edc_bench("replay", "rec", cwd=tmp_path)
    assert proc.returncode == 13, proc.stdout + proc.stderr
    assert "changed after the test (its integrity manifest): record.json's 'operator'" in proc.stdout


@pytest.mark.parametrize(("damage", "named"), [
    (lambda f: (f / "can.log").write_text((f / "can.log").read_text().replace("120#", "120#0", 1)), "can.log"),
    (lambda f: (f / "trace.mf4").unlink(), "trace.mf4 (missing)"),
    (lambda f: (f / "record.json").write_text(json.dumps({k: v for k, v in json.loads(
        (f / "record.json").read_text()).items() if k != "integrity"})), "integrity manifest (removed or damaged)"),
])
def test_a_changed_or_missing_file_and_a_removed_manifest_are_named(written: Path, tmp_path: Path, damage,
                                                                   named: str) -> None:
    folder = copy(written, tmp_path)
    damage(folder)
    with pytest.raises(ConfigError, match="changed after its test wrote it") as caught:
        load_record(folder)
    assert named in str(caught.value)


@pytest.mark.slow  # the default suite's 5 minutes; CI's slow pass runs it
def test_the_report_written_into_the_folder_leaves_it_readable(written: Path, tmp_path: Path) -> None:
    folder = copy(written, tmp_path)
    for _ in range(2):  # report.pdf and its pages' PNGs are the report's, not the test's: not in the manifest
        proc = edc_bench("report", "rec", cwd=tmp_path)
        assert proc.returncode == 0, proc.stderr
    assert load_record(folder).verdict == "PASS"
