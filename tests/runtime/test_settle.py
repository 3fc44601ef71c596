"""One decision for an interrupt: before a command settles its outcome, a Ctrl-C a library swallowed is still
Ctrl-C; after it, a signal is noted and changes nothing (the command's words and files stand)."""

from __future__ import annotations

import os
import signal
from pathlib import Path

import pytest

from edc_bench.runtime.signals import interrupted_after_settling, raise_on_interrupt, settle


@pytest.fixture(scope="module")
def worn_record(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A worn valve's record folder, to draw reports of."""
    from edc_bench.cli import main

    out = tmp_path_factory.mktemp("settle-record")
    assert main(["test", "--valve", "worn", "--no-history", "--no-figure", "--plain", "--out", str(out)]) == 11
    (folder,) = out.iterdir()
    return folder


def _swallowed_interrupt() -> None:
    """What a library that catches everything does with a Ctrl-C landing in it."""
    try:
        os.kill(os.getpid(), signal.SIGINT)
        for _ in range(1000):  # the handler runs at the next bytecode
            pass
    except KeyboardInterrupt:
        pass


def test_a_swallowed_interrupt_is_raised_when_the_command_settles() -> None:
    with raise_on_interrupt():
        _swallowed_interrupt()
        with pytest.raises(KeyboardInterrupt):
            settle()


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_a_signal_after_settling_is_noted_and_raises_nothing(sig: int) -> None:
    with raise_on_interrupt():
        settle()
        os.kill(os.getpid(), sig)
        for _ in range(1000):
            pass
        assert interrupted_after_settling() == 1
    with raise_on_interrupt():  # the next command starts unsettled
        with pytest.raises(KeyboardInterrupt):
            os.kill(os.getpid(), signal.SIGINT)
            for _ in range(1000):
                pass


def test_report_with_an_interrupt_swallowed_while_drawing_announces_nothing_and_leaves_no_file(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch,
        worn_record: Path) -> None:
    """The CI failure: a Ctrl-C landing in a library that ran on drew and announced the report, then exited 130."""
    import edc_bench.records.report as report
    from edc_bench.cli import main
    from edc_bench.cli.exit_codes import ExitCode

    drawn = report.draw_report

    def draw_swallowing(*args: object, **kwargs: object) -> object:
        _swallowed_interrupt()
        return drawn(*args, **kwargs)

    monkeypatch.setattr(report, "draw_report", draw_swallowing)
    out_dir = tmp_path / "report"
    code = main(["report", str(worn_record), "--out", str(out_dir)])
    out, err = capsys.readouterr()
    assert code == ExitCode.INTERRUPTED, err
    assert out == "" and err.strip() == "edc-bench report: interrupted"
    assert list(out_dir.iterdir()) == []


def test_an_interrupted_report_leaves_the_report_that_was_there_whole(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch,
        worn_record: Path) -> None:
    """The review's finding: the interrupt removed the new report.pdf after it had replaced the old one, leaving
    the old page images without a PDF. Drawn beside and put in place only once settled, the old report stays."""
    import edc_bench.records.report as report
    from edc_bench.cli import main
    from edc_bench.cli.exit_codes import ExitCode

    out_dir = tmp_path / "report"
    assert main(["report", str(worn_record), "--out", str(out_dir)]) == 0
    capsys.readouterr()
    before = {p.name: p.read_bytes() for p in out_dir.iterdir()}
    assert set(before) == {"report.pdf", "report-page.png", "report-page-2.png"}
    drawn = report.draw_report

    def draw_then_swallow(*args: object, **kwargs: object) -> object:
        result = drawn(*args, **kwargs)  # the new files written (beside), then a Ctrl-C a library swallows
        _swallowed_interrupt()
        return result

    monkeypatch.setattr(report, "draw_report", draw_then_swallow)
    assert main(["report", str(worn_record), "--out", str(out_dir)]) == ExitCode.INTERRUPTED
    assert {p.name: p.read_bytes() for p in out_dir.iterdir()} == before  # nothing else, nothing changed
