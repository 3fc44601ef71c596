"""A signal after the test has ended leaves the verdict its record holds: said once, with the verdict's exit code.

The tester's finding: Ctrl-C or SIGTERM arriving after the loop ended printed the PASS verdict, then "interrupted
by the operator; the record is written (INVALID)", exit 130, while record.json and the history said PASS (13 of
13 tries). Here the signal is sent at the moment the verdict is shown (the record written), as a technician's
Ctrl-C lands when the verdict appears.
"""

from __future__ import annotations

import os
import signal
from pathlib import Path

import pytest

from edc_bench.cli import main
from edc_bench.cli.exit_codes import ExitCode
from edc_bench.records.reader import load_record


def _signal_when_the_verdict_is_shown(monkeypatch: pytest.MonkeyPatch, sig: int, times: int = 1) -> None:
    import edc_bench.cli.test_cmd as test_cmd

    shown = test_cmd._report
    left = [times]

    def report_then_signal(*args: object, **kwargs: object) -> None:
        shown(*args, **kwargs)
        if left[0] > 0:
            left[0] -= 1
            os.kill(os.getpid(), sig)

    monkeypatch.setattr(test_cmd, "_report", report_then_signal)


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["ctrl-c", "sigterm"])
def test_a_signal_after_the_test_leaves_its_pass_and_says_so(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                             capsys: pytest.CaptureFixture[str], sig: int) -> None:
    _signal_when_the_verdict_is_shown(monkeypatch, sig)
    code = main(["test", "--valve", "new", "--no-history", "--plain", "--out", str(tmp_path)])
    out, err = capsys.readouterr()
    (folder,) = tmp_path.iterdir()
    assert load_record(folder).verdict == "PASS"
    assert code == ExitCode.PASS, err
    assert "verdict: PASS" in out or "PASS" in out
    assert "interrupted by the operator" not in err and "INVALID" not in err, err
    assert f"interrupted after the test had ended: PASS stands, as its record {folder} holds it" in err
    assert (folder / "report.png").exists()  # the guard held the signal: the figure is drawn all the same


def test_a_signal_after_a_marginal_says_its_retest_was_not_run(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                               capsys: pytest.CaptureFixture[str]) -> None:
    _signal_when_the_verdict_is_shown(monkeypatch, signal.SIGINT)
    code = main(["test", "--valve", "clearance=0.185", "--no-history", "--plain", "--no-figure",
                 "--out", str(tmp_path)])
    out, err = capsys.readouterr()
    (folder,) = tmp_path.iterdir()  # no retest folder
    assert load_record(folder).verdict == "MARGINAL"
    assert code == ExitCode.MARGINAL, err
    assert "MARGINAL stands" in err and "the retest was not run: test the valve again for its decision" in err


def test_a_signal_during_the_test_is_still_the_operators_interrupt(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                                  capsys: pytest.CaptureFixture[str]) -> None:
    """The control: cut short mid-test, the record says INVALID and the exit is 130."""
    import edc_bench.bench as bench

    ticks = [0]
    polled = bench.stop_requested

    def interrupt_at_tick_2000() -> bool:
        ticks[0] += 1
        if ticks[0] == 2000:
            os.kill(os.getpid(), signal.SIGINT)
        return polled()

    monkeypatch.setattr(bench, "stop_requested", interrupt_at_tick_2000)
    code = main(["test", "--valve", "new", "--no-history", "--plain", "--no-figure", "--out", str(tmp_path)])
    _, err = capsys.readouterr()
    (folder,) = tmp_path.iterdir()
    assert code == ExitCode.INTERRUPTED, err
    assert load_record(folder).verdict == "INVALID"
    assert "interrupted by the operator; the record is written (INVALID)" in err
