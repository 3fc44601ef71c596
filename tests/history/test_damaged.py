"""A damaged file is named, and work goes on where it can (#52): a damaged station history says how to keep testing
and how to rebuild it; ``history --add`` indexes every good folder and lists the bad ones."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest
from helpers import edc_bench

from edc_bench.bench import run_simulated_test
from edc_bench.config import load_variant
from edc_bench.records.record import write_record


@pytest.fixture(scope="module")
def good_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_record(run_simulated_test(load_variant(), "new", 5), tmp_path_factory.mktemp("records"),
                        figure=False)


@pytest.mark.slow  # three tests as processes: CI's slow pass
def test_a_damaged_history_says_how_to_test_on_and_how_to_rebuild(good_dir: Path, tmp_path: Path) -> None:
    path = tmp_path / "history.sqlite"
    url = f"sqlite:///{path}"
    assert edc_bench("history", "--add", str(good_dir), "--db", url).returncode == 0
    with path.open("r+b") as handle:  # pages overwritten, the header left: SQLite's "malformed"
        handle.seek(100)
        handle.write(b"\x00damaged" * 400)
    # a listing is refused, saying what to do; a test goes on, its record kept, and says the same after it
    for argv, code in ((("history",), 2), (("test", "--valve-id", "V-1", "--no-figure"), 0)):
        proc = edc_bench(*argv, "--db", url, cwd=tmp_path)
        said = proc.stderr.strip().splitlines()
        assert proc.returncode == code and "Traceback" not in proc.stderr, proc.stderr
        line = next(line for line in said if "damaged" in line)
        assert "--no-history" in line and f"mv {path} {path}.damaged" in line and "history --add" in line, line
    path.write_bytes(b"not a database at all, not even its header")
    refused = edc_bench("test", "--valve-id", "V-1", "--db", url, cwd=tmp_path)
    assert refused.returncode == 2 and "--no-history" in refused.stderr and len(refused.stderr.splitlines()) == 1
    kept = edc_bench("test", "--valve-id", "V-1", "--no-history", "--out", str(tmp_path / "rec"), cwd=tmp_path)
    assert kept.returncode == 0, kept.stderr  # testing goes on


def test_history_add_indexes_every_good_folder_and_lists_the_bad_ones(good_dir: Path, tmp_path: Path) -> None:
    url = f"sqlite:///{tmp_path / 'history.sqlite'}"
    good = tmp_path / "good"
    shutil.copytree(good_dir, good)
    damaged, empty = tmp_path / "damaged", tmp_path / "empty"
    shutil.copytree(good_dir, damaged)
    (damaged / "record.json").write_text("{ not json")
    empty.mkdir()
    proc = edc_bench("history", "--add", str(damaged), str(good), str(empty), "--db", url)
    assert proc.returncode == 2 and "Traceback" not in proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert lines[0].startswith("indexed 1 new record folder(s)") and "2 not indexed (below)" in lines[0]
    assert len(lines) == 3 and all(line.startswith("edc-bench history: not indexed: ") for line in lines[1:])
    assert str(damaged) in lines[1] and str(empty) in lines[2]
    assert len(json.loads(edc_bench("history", "--json", "--db", url).stdout)) == 1
    # nothing good at all: the history is not made
    none = edc_bench("history", "--add", str(empty), "--db", f"sqlite:///{tmp_path / 'other.sqlite'}")
    assert none.returncode == 2 and not (tmp_path / "other.sqlite").exists()
