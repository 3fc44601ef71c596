"""A full disk costs neither the verdict nor, where any room is left, the record (#13, defect 4)."""

from __future__ import annotations

import errno
import json
from pathlib import Path

import pytest

from edc_bench.cli import main
from edc_bench.cli.exit_codes import ExitCode


def _disk_full_under(monkeypatch: pytest.MonkeyPatch, folder: Path) -> None:
    """Every record file written under ``folder`` fails with ENOSPC (the CAN log streamed there too)."""
    from edc_bench import paths
    from edc_bench.records import stream

    original = paths.atomic_write

    def atomic_write(path, *args, **kwargs):
        if Path(path).resolve().is_relative_to(folder.resolve()):
            raise OSError(errno.ENOSPC, "No space left on device", str(path))
        return original(path, *args, **kwargs)

    for module in ("edc_bench.paths", "edc_bench.records.writer", "edc_bench.records.mdf"):
        monkeypatch.setattr(f"{module}.atomic_write", atomic_write, raising=False)

    def no_room(self) -> None:
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(stream.StreamingCanLog, "_flush_new", no_room)


def test_a_full_records_disk_saves_the_record_elsewhere_and_says_where(tmp_path: Path, monkeypatch, capsys) -> None:
    out = tmp_path / "records"
    monkeypatch.setattr("tempfile.tempdir", str(tmp_path / "tmp"))
    (tmp_path / "tmp").mkdir()
    _disk_full_under(monkeypatch, out)
    code = main(["test", "--valve", "worn", "--duration-s", "8", "--out", str(out), "--no-figure",
                 "--db", f"sqlite:///{tmp_path / 'history.db'}", "--plain"])
    err = capsys.readouterr().err
    assert code == ExitCode.INVALID, err  # 8 s: too short to converge, judged as usual
    assert "could not be written under" in err and "No space left on device" in err
    saved = list((tmp_path / "tmp").glob("edc-bench-record-*"))
    assert len(saved) == 1 and "history --add" in err
    doc = json.loads((saved[0] / "record.json").read_text())
    assert any("could not be written under" in e for e in doc["loop"]["events"])
    assert any("can.log could not be streamed" in e for e in doc["loop"]["events"])
    assert (saved[0] / "can.log").stat().st_size > 0 and (saved[0] / "trace.mf4").is_file()
    # a record in the temp folder is not put in the history (it is to be moved, then added): none was started
    assert not (tmp_path / "history.db").exists()


def test_a_record_missing_its_trace_says_so(tmp_path: Path, monkeypatch, capsys) -> None:
    """The disk fills while the big trace.mf4 is written: record.json, the smallest, is still written and names
    what is missing."""
    import edc_bench.records.record as record_module

    def no_room(path, *args, **kwargs):
        raise OSError(errno.ENOSPC, "No space left on device", str(path))

    monkeypatch.setattr(record_module, "write_trace_mf4", no_room)
    out = tmp_path / "records"
    code = main(["test", "--valve", "worn", "--duration-s", "8", "--out", str(out), "--no-figure", "--no-history",
                 "--plain"])
    err = capsys.readouterr().err
    assert code == ExitCode.INVALID
    assert "the record is incomplete: trace: OSError: [Errno 28] No space left on device" in err
    (folder,) = out.iterdir()
    doc = json.loads((folder / "record.json").read_text())
    assert doc["files"]["trace"] is None and "No space left" in doc["files"]["trace_error"]
    assert doc["files"]["can_log"] == "can.log"


def test_no_room_anywhere_prints_the_verdict_and_exits_74(tmp_path: Path, monkeypatch, capsys) -> None:
    out = tmp_path / "records"
    monkeypatch.setattr("tempfile.tempdir", str(tmp_path))
    _disk_full_under(monkeypatch, tmp_path)
    code = main(["test", "--valve", "worn", "--duration-s", "8", "--out", str(out), "--no-figure", "--no-history",
                 "--plain"])
    captured = capsys.readouterr()
    assert code == ExitCode.RECORD_NOT_WRITTEN == 74
    assert "verdict: INVALID" in captured.out and "record: not written" in captured.out
    assert "the record could not be written" in captured.err and "free space" in captured.err
    assert "Traceback" not in captured.err


def test_calibrate_without_room_for_a_record_writes_no_baseline_and_exits_74(tmp_path: Path, monkeypatch,
                                                                              capsys) -> None:
    import edc_bench.records.record as record_module

    def no_room(*args, **kwargs):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(record_module, "write_json", no_room)
    baseline = tmp_path / "baseline.json"
    code = main(["calibrate", "--valve", "new", "--out", str(tmp_path / "records"), "--baseline-file", str(baseline)])
    err = capsys.readouterr().err
    assert code == ExitCode.RECORD_NOT_WRITTEN
    assert "the record of test 1/1 could not be written" in err and "no baseline was written" in err
    assert "Traceback" not in err and not baseline.exists()


def test_a_bug_in_a_command_says_so_with_exit_70(monkeypatch, capsys) -> None:
    # the net under every command: its own message and the traceback, never a second error from the net itself
    import edc_bench.cli.variants_cmd as variants_cmd

    def broken(args):
        raise RuntimeError("deliberate")

    monkeypatch.setattr(variants_cmd, "run", broken)
    assert main(["variants"]) == ExitCode.INTERNAL_ERROR
    err = capsys.readouterr().err
    assert "edc-bench variants: internal error: RuntimeError: deliberate" in err
    assert "This is a bug in edc-bench" in err and "NameError" not in err
