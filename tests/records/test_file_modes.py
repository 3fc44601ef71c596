"""The shop's files get the mode any new file gets (0644 under umask 022), not mkstemp's 0600: records, the
report, history exports and baselines are read by the shop's other accounts."""

from __future__ import annotations

import os
import stat
from collections.abc import Iterator
from pathlib import Path

import pytest

from edc_bench.cli import main


@pytest.fixture()
def umask_022() -> Iterator[None]:
    old = os.umask(0o022)
    try:
        yield
    finally:
        os.umask(old)


def modes(folder: Path) -> dict[str, int]:
    return {p.name: stat.S_IMODE(p.stat().st_mode) for p in folder.iterdir() if p.is_file()}


def test_a_tests_record_its_report_and_an_export_are_0644_under_umask_022(umask_022: None, tmp_path: Path,
                                                                         capsys: pytest.CaptureFixture[str]) -> None:
    db = f"sqlite:///{tmp_path / 'history.sqlite'}"
    assert main(["test", "--out", str(tmp_path / "rec"), "--db", db, "--valve-id", "V-1",
                 "--no-figure"]) == 0
    record = next((tmp_path / "rec").iterdir())
    assert main(["report", str(record)]) == 0
    assert main(["history", "--db", db, "--csv", str(tmp_path / "tests.csv")]) == 0
    capsys.readouterr()
    found = {**modes(record), "tests.csv": stat.S_IMODE((tmp_path / "tests.csv").stat().st_mode)}
    assert {"record.json", "report.pdf", "report-page.png", "report-page-2.png", "tests.csv"} <= set(found)
    assert {name: oct(mode) for name, mode in found.items() if mode != 0o644} == {}


def test_the_mode_follows_the_umask(tmp_path: Path) -> None:
    from edc_bench.paths import atomic_write, umask

    old = os.umask(0o027)
    try:
        assert umask() == 0o027
        atomic_write(tmp_path / "a.txt", lambda f: f.write(b"x"))
    finally:
        os.umask(old)
    assert stat.S_IMODE((tmp_path / "a.txt").stat().st_mode) == 0o640
