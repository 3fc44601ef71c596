"""A full disk costs neither the verdict nor, where any room is left, the record (#13, defect 4); and wherever it
strikes, the exit code is 74 with one line, never a record missing a part passed off as a clean exit (#52)."""

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
    what is missing; the verdict stands, the exit code says the record is not whole."""
    import edc_bench.records.record as record_module

    def no_room(path, *args, **kwargs):
        raise OSError(errno.ENOSPC, "No space left on device", str(path))

    monkeypatch.setattr(record_module, "write_trace_mf4", no_room)
    out = tmp_path / "records"
    code = main(["test", "--valve", "worn", "--duration-s", "8", "--out", str(out), "--no-figure", "--no-history",
                 "--plain"])
    captured = capsys.readouterr()
    err = captured.err
    assert code == ExitCode.RECORD_NOT_WRITTEN  # not INVALID's 12, as if the record were whole
    assert "verdict: INVALID" in captured.out
    assert "error: the record is incomplete: trace: OSError: [Errno 28] No space left on device" in err
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


def test_no_trace_and_a_cut_can_log_is_no_clean_exit(tmp_path: Path, monkeypatch, capsys) -> None:
    """The disk fills part way through the test: the CAN log's streaming stops after a few batches, and neither
    the trace nor the whole CAN log fits at the end. A new valve's PASS used to exit 0 with a warning."""
    import edc_bench.records.record as record_module
    from edc_bench.records import stream

    def no_room(path, *args, **kwargs):
        raise OSError(errno.ENOSPC, "No space left on device", str(path))

    def flush_until_full(self) -> None:
        stop = min(self.frames.count, self.written + 100)
        stream.log_frames(self._writer, self.frames, self.written, stop)  # a hundred frames fit ...
        self.written = stop
        self._file.flush()
        raise OSError(errno.ENOSPC, "No space left on device")  # ... then the disk is full

    monkeypatch.setattr(stream.StreamingCanLog, "_flush_new", flush_until_full)
    monkeypatch.setattr(record_module, "write_trace_mf4", no_room)
    monkeypatch.setattr(record_module, "write_can_log", no_room)
    out = tmp_path / "records"
    code = main(["test", "--valve", "new", "--out", str(out), "--no-figure", "--no-history", "--plain"])
    captured = capsys.readouterr()
    assert code == ExitCode.RECORD_NOT_WRITTEN, captured.err
    assert "verdict: PASS" in captured.out  # the verdict stands ...
    errors = [line for line in captured.err.splitlines() if "error:" in line]
    assert len(errors) == 1 and "the record is incomplete: trace: " in errors[0] and "can_log: " in errors[0]
    assert "free space on the disk, then test the valve again" in errors[0]  # ... and what to do is said
    assert "Traceback" not in captured.err
    (folder,) = out.iterdir()
    doc = json.loads((folder / "record.json").read_text())
    assert doc["files"]["trace"] is None and doc["files"]["can_log"] is None
    assert "No space left" in doc["files"]["trace_error"] and "No space left" in doc["files"]["can_log_error"]
    assert any("can.log could not be streamed" in event for event in doc["loop"]["events"])
    assert 0 < len((folder / "can.log").read_text().splitlines()) <= 100  # the cut log, named incomplete above


@pytest.mark.parametrize("where", ["atomic write", "elsewhere"])
def test_report_on_a_full_disk_exits_74_in_one_line(tmp_path: Path, monkeypatch, capsys, where: str) -> None:
    """A full disk while the report is written: exit 74 and one line naming the file (a write's ENOSPC names no
    file itself), never an internal error's traceback."""
    import os

    out = tmp_path / "records"
    assert main(["test", "--valve", "worn", "--out", str(out), "--no-figure", "--no-history", "--plain"]) == 11
    (folder,) = out.iterdir()
    capsys.readouterr()

    def no_room(*args, **kwargs):
        raise OSError(errno.ENOSPC, "No space left on device")  # as os.write and fsync raise it: no file named

    if where == "atomic write":
        monkeypatch.setattr(os, "fsync", no_room)
    else:
        monkeypatch.setattr("edc_bench.records.report.draw_report", no_room)
    code = main(["report", str(folder), "--out", str(tmp_path / "report")])
    captured = capsys.readouterr()
    assert code == ExitCode.RECORD_NOT_WRITTEN == 74, captured.err
    assert captured.out == "" and "Traceback" not in captured.err
    (line,) = captured.err.splitlines()
    assert line.startswith("edc-bench report: error: ") and "the disk is full: free space, then run it again" in line
    if where == "atomic write":
        assert f"{tmp_path / 'report' / 'report.pdf'}: No space left on device" in line
        assert not list((tmp_path / "report").iterdir())  # no temporary file left, no report.pdf


def test_calibrate_on_a_full_disk_writes_no_baseline_and_exits_74(tmp_path: Path, monkeypatch, capsys) -> None:
    """The baseline file does not fit: 74 (a full disk), not 2 (bad input); the earlier baseline is unchanged."""
    from edc_bench import paths

    baseline = tmp_path / "baseline.toml"
    original = paths.atomic_write

    def atomic_write(path, *args, **kwargs):
        if Path(path) == baseline:
            raise OSError(errno.ENOSPC, "No space left on device", str(path))
        return original(path, *args, **kwargs)

    monkeypatch.setattr(paths, "atomic_write", atomic_write)
    code = main(["calibrate", "--valve", "new", "--out", str(tmp_path / "records"), "--baseline-file", str(baseline)])
    err = capsys.readouterr().err
    assert code == ExitCode.RECORD_NOT_WRITTEN, err
    assert f"{baseline}: cannot write the baseline (No space left on device)" in err and "free space" in err
    assert not baseline.exists() and "Traceback" not in err


def test_calibrate_with_a_record_missing_its_trace_writes_no_baseline(tmp_path: Path, monkeypatch, capsys) -> None:
    import edc_bench.records.record as record_module

    def no_room(path, *args, **kwargs):
        raise OSError(errno.ENOSPC, "No space left on device", str(path))

    monkeypatch.setattr(record_module, "write_trace_mf4", no_room)
    baseline = tmp_path / "baseline.toml"
    code = main(["calibrate", "--valve", "new", "--out", str(tmp_path / "records"), "--baseline-file", str(baseline)])
    err = capsys.readouterr().err
    assert code == ExitCode.RECORD_NOT_WRITTEN, err
    assert "the record of test 1/1 in " in err and "is incomplete (trace: " in err and "no baseline was written" in err
    assert not baseline.exists()


def test_tune_on_a_full_disk_exits_74_and_leaves_the_variant_file_whole(tmp_path: Path, monkeypatch, capsys) -> None:
    from helpers import write_new_pump_type

    path = write_new_pump_type(tmp_path / "variants")
    before = path.read_text(encoding="utf-8")
    write_text = Path.write_text

    def part_then_full(self: Path, *args, **kwargs):
        if self.name.endswith(".tune"):
            write_text(self, "[controller]\nkp_v_per", encoding="utf-8")  # what fitted
            raise OSError(errno.ENOSPC, "No space left on device")
        return write_text(self, *args, **kwargs)

    monkeypatch.setattr(Path, "write_text", part_then_full)
    code = main(["tune", "--variant", str(path), "--write"])
    captured = capsys.readouterr()
    assert code == ExitCode.RECORD_NOT_WRITTEN, captured.err
    assert "cannot write the gains (No space left on device)" in captured.err and "Traceback" not in captured.err
    assert path.read_text(encoding="utf-8") == before  # the variant file whole, as it was
    assert [p.name for p in path.parent.iterdir()] == [path.name]  # and no part-written file beside it


def _no_room_for_the_figure(monkeypatch: pytest.MonkeyPatch) -> None:
    """The disk is full when report.png is written, and only then (the data files fit)."""
    from edc_bench import paths

    original = paths.atomic_write

    def no_room(path, *args, **kwargs):
        if Path(path).name == "report.png":
            raise OSError(errno.ENOSPC, "No space left on device", str(path))
        return original(path, *args, **kwargs)

    monkeypatch.setattr(paths, "atomic_write", no_room)


def test_a_figure_the_full_disk_left_unwritten_is_named_and_exits_74(tmp_path: Path, monkeypatch, capsys) -> None:
    """The tester's finding: with the disk full when report.png was written, the figure was missing, exit 0,
    nothing said. The data is whole (the figure is drawn again from it): the verdict stands, one line names the
    file and how to draw it later."""
    _no_room_for_the_figure(monkeypatch)
    out = tmp_path / "records"
    code = main(["test", "--valve", "new", "--out", str(out), "--no-history", "--plain"])
    captured = capsys.readouterr()
    (folder,) = out.iterdir()
    assert "verdict: PASS" in captured.out
    assert code == ExitCode.RECORD_NOT_WRITTEN, captured.err
    assert (f"error: {folder / 'report.png'} could not be written (OSError: [Errno 28] No space left on device"
            in captured.err)
    assert f"edc-bench report {folder}" in captured.err
    assert json.loads((folder / "record.json").read_text())["verdict"] == "PASS"


def test_a_full_records_disk_leaves_no_half_written_folder_under_out(tmp_path: Path, monkeypatch, capsys) -> None:
    """The tester's finding: with the disk full at record.json, the record went to the temp folder as promised, but
    a folder with only a partial can.log stayed under --out, unmentioned. Its CAN log is whole in the saved
    record: the folder is removed."""
    from edc_bench.records import record as record_module

    out = tmp_path / "records"
    monkeypatch.setattr("tempfile.tempdir", str(tmp_path / "tmp"))
    (tmp_path / "tmp").mkdir()
    written = record_module.write_json

    def no_room_under_out(path, *args, **kwargs):
        if Path(path).resolve().is_relative_to(out.resolve()):
            raise OSError(errno.ENOSPC, "No space left on device", str(path))
        return written(path, *args, **kwargs)

    monkeypatch.setattr(record_module, "write_json", no_room_under_out)
    code = main(["test", "--valve", "new", "--out", str(out), "--no-figure", "--no-history", "--plain"])
    err = capsys.readouterr().err
    assert code == ExitCode.PASS, err  # whole, in the temp folder, and said
    (saved,) = (tmp_path / "tmp").glob("edc-bench-record-*")
    assert f"it was saved to {saved}" in err
    assert (saved / "can.log").stat().st_size > 0
    assert list(out.iterdir()) == [], "a half-written record folder was left under --out"


def test_a_figure_that_fails_to_draw_is_a_warning_and_a_marginal_is_still_retested(tmp_path: Path, monkeypatch,
                                                                                   capsys) -> None:
    """A fault in the figure's drawing is no full disk: the verdict's own code, a warning that names it as a bug,
    and a MARGINAL's retest runs (the review's finding: it had been exit 74, 'free space on the disk', no retest)."""
    from edc_bench.records import figure

    def broken(*args, **kwargs):
        raise ValueError("a drawing bug")

    monkeypatch.setattr(figure, "draw_report_figure", broken)
    out = tmp_path / "records"
    code = main(["test", "--valve", "clearance=0.185", "--out", str(out), "--no-history", "--plain"])
    err = capsys.readouterr().err
    assert len(list(out.iterdir())) == 2, err  # the MARGINAL and its retest
    assert code in (ExitCode.PASS, ExitCode.MARGINAL, ExitCode.FAIL), err  # the pair's decision
    assert "could not be drawn (ValueError: a drawing bug): a bug in edc-bench" in err
    assert "disk is full" not in err


def test_a_marginals_figure_lost_to_a_full_disk_still_retests_then_exits_74(tmp_path: Path, monkeypatch,
                                                                            capsys) -> None:
    _no_room_for_the_figure(monkeypatch)
    out = tmp_path / "records"
    code = main(["test", "--valve", "clearance=0.185", "--out", str(out), "--no-history", "--plain"])
    captured = capsys.readouterr()
    assert len(list(out.iterdir())) == 2, captured.err  # retested all the same
    assert "decision:" in captured.out
    assert code == ExitCode.RECORD_NOT_WRITTEN, captured.err
