"""Exit codes of ``edc-bench``, one per outcome a script may act on."""

from __future__ import annotations

import enum

from edc_bench.diagnosis.verdict import Verdict


class ExitCode(enum.IntEnum):
    """Process exit codes.

    ``PASS``..``INVALID`` are the verdict of a bench test; the others say the
    command could not do its job.
    """

    OK = 0
    PASS = 0
    MARGINAL = 10
    FAIL = 11
    INVALID = 12
    NOT_REPRODUCED = 13  # edc-bench replay: the log does not give the recorded result
    STATION_NOT_READY = 14  # edc-bench check-station: NO-GO
    BAD_INPUT = 2
    RIG_ERROR = 3
    INTERRUPTED = 130
    INTERNAL_ERROR = 70


def exit_code_for(verdict: str) -> ExitCode:
    """The exit code of a verdict (OK for a test judged without classification)."""
    return {Verdict.PASS: ExitCode.PASS, Verdict.MARGINAL: ExitCode.MARGINAL, Verdict.FAIL: ExitCode.FAIL,
            Verdict.INVALID: ExitCode.INVALID}.get(verdict, ExitCode.OK)
