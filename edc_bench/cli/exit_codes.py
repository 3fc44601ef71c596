"""Exit codes of ``edc-bench``, one per outcome a script may act on."""

from __future__ import annotations

import enum

from edc_bench.verdict.verdicts import Verdict


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
    NOT_REPRODUCED = 13  # replay: the log does not give the recorded result; classify FOLDER: not the recorded verdict
    STATION_NOT_READY = 14  # edc-bench check-station: NO-GO
    RIG_NOT_CONFORMING = 15  # edc-bench rig-check: NO-GO
    HISTORY_NOT_AS_INDEXED = 16  # edc-bench history --verify: a record folder missing or altered since indexed
    RIG_DRIFTED = 17  # edc-bench rig-selfcheck: NO-GO, a sensor or the reference valve drifted
    NO_REFERENCE_VALVE = 18  # edc-bench rig-selfcheck: no reference valve is registered for the station
    BAD_INPUT = 2
    RIG_ERROR = 3
    INTERRUPTED = 130
    INTERNAL_ERROR = 70
    RECORD_NOT_WRITTEN = 74  # a full disk: a record (or a baseline, a report) not written whole (sysexits' EX_IOERR)


def exit_code_for(verdict: str) -> ExitCode:
    """The exit code of a verdict (OK for a test judged without classification)."""
    return {Verdict.PASS: ExitCode.PASS, Verdict.MARGINAL: ExitCode.MARGINAL, Verdict.FAIL: ExitCode.FAIL,
            Verdict.INVALID: ExitCode.INVALID}.get(verdict, ExitCode.OK)


#: What each code means, in the words of docs/command-line.md's exit-code table and every command's ``--help``.
MEANINGS: dict[int, str] = {
    ExitCode.PASS: "PASS (a test, a classification, a replayed raw log), or done",
    ExitCode.MARGINAL: "MARGINAL: near the boundary, retest",
    ExitCode.FAIL: "FAIL: replace the valve",
    ExitCode.INVALID: "INVALID: the test is not to be trusted (the reasons are printed)",
    ExitCode.NOT_REPRODUCED: "replay: the log does not give the recorded result; classify FOLDER: the verdict is not "
                             "the record's, or the record's does not follow from its own figures (both are printed)",
    ExitCode.STATION_NOT_READY: "check-station: NO-GO (the advice is printed)",
    ExitCode.RIG_NOT_CONFORMING: "rig-check: NO-GO, the rig breaks an ICD rule (the failed checks are printed)",
    ExitCode.HISTORY_NOT_AS_INDEXED: "history --verify: a record folder is missing or changed since it was indexed "
                                     "(each is listed)",
    ExitCode.RIG_DRIFTED: "rig-selfcheck: NO-GO, the rig's sensors or the reference valve drifted (what drifted and "
                          "what to do are printed)",
    ExitCode.NO_REFERENCE_VALVE: "rig-selfcheck: no reference valve is registered for this station (the command "
                                 "that registers one is printed)",
    ExitCode.BAD_INPUT: "bad input: the message names what was wrong and how to fix it; nothing was done",
    ExitCode.RIG_ERROR: "rig or bus error (the bus does not open, the rig process does not start)",
    ExitCode.INTERNAL_ERROR: "internal error: a bug in edc-bench (the details are printed)",
    ExitCode.INTERRUPTED: "interrupted (Ctrl-C or SIGTERM); a started test's record is still written, nothing "
                          "else cut short is saved (a signal once a test has ended leaves its verdict's code)",
    ExitCode.RECORD_NOT_WRITTEN: "a full disk: a record, baseline or report could not be written whole (a test's "
                                 "verdict is printed all the same)",
}

#: What 0 means for each command (default: done).
SUCCESS: dict[str, str] = {
    "test": "PASS: the valve is reusable",
    "classify": "PASS: the valve is reusable",
    "replay": "the record is reproduced exactly (a raw log: PASS)",
    "check-station": "GO: this PC holds the loop rate",
    "rig-check": "GO: the rig kept every ICD rule checked",
    "rig-selfcheck": "GO: the reference valve measures as registered (with --register: registered)",
    "rig": "the rig was stopped (Ctrl-C or SIGTERM)",
}

#: The codes each command can return; every command can also return 2, 70, 74 and 130 (:data:`ALWAYS`).
COMMAND_CODES: dict[str, tuple[int, ...]] = {
    "test": (ExitCode.PASS, ExitCode.MARGINAL, ExitCode.FAIL, ExitCode.INVALID, ExitCode.RIG_ERROR,
             ExitCode.RECORD_NOT_WRITTEN),
    "rig": (ExitCode.OK,),
    "variants": (ExitCode.OK,),
    "tune": (ExitCode.OK,),
    "calibrate": (ExitCode.OK, ExitCode.INVALID, ExitCode.RIG_ERROR, ExitCode.RECORD_NOT_WRITTEN),
    "train": (ExitCode.OK,),
    "classify": (ExitCode.PASS, ExitCode.MARGINAL, ExitCode.FAIL, ExitCode.INVALID, ExitCode.NOT_REPRODUCED),
    "evaluate": (ExitCode.OK,),
    "paper": (ExitCode.OK,),
    "study-boundary": (ExitCode.OK,),
    "perf": (ExitCode.OK,),
    "replay": (ExitCode.OK, ExitCode.MARGINAL, ExitCode.FAIL, ExitCode.INVALID, ExitCode.NOT_REPRODUCED),
    "history": (ExitCode.OK, ExitCode.HISTORY_NOT_AS_INDEXED),
    "label": (ExitCode.OK,),
    "report": (ExitCode.OK,),
    "check-station": (ExitCode.OK, ExitCode.STATION_NOT_READY),
    "rig-check": (ExitCode.OK, ExitCode.RIG_NOT_CONFORMING, ExitCode.RIG_ERROR),
    "session": (ExitCode.OK,),
    "rig-selfcheck": (ExitCode.OK, ExitCode.RIG_ERROR, ExitCode.RIG_DRIFTED, ExitCode.NO_REFERENCE_VALVE),
    "web": (ExitCode.OK,),
}

#: Codes any command can return: bad input (argparse too), a bug, a full disk, Ctrl-C or SIGTERM.
ALWAYS = (ExitCode.BAD_INPUT, ExitCode.INTERNAL_ERROR, ExitCode.RECORD_NOT_WRITTEN, ExitCode.INTERRUPTED)

#: The short names of README's sentence ("Exit codes: 0 PASS, 10 MARGINAL, ...").
SHORT_NAMES: dict[int, str] = {
    ExitCode.PASS: "PASS", ExitCode.MARGINAL: "MARGINAL", ExitCode.FAIL: "FAIL", ExitCode.INVALID: "INVALID",
    ExitCode.NOT_REPRODUCED: "not as recorded", ExitCode.STATION_NOT_READY: "station NO-GO",
    ExitCode.RIG_NOT_CONFORMING: "rig NO-GO", ExitCode.HISTORY_NOT_AS_INDEXED: "history not as indexed",
    ExitCode.RIG_DRIFTED: "rig self-check NO-GO", ExitCode.NO_REFERENCE_VALVE: "no reference valve",
    ExitCode.BAD_INPUT: "bad input", ExitCode.RIG_ERROR: "rig or bus error", ExitCode.INTERNAL_ERROR: "internal error",
    ExitCode.INTERRUPTED: "interrupted", ExitCode.RECORD_NOT_WRITTEN: "record not written",
}


def command_codes(command: str) -> list[int]:
    """Every code ``command`` can return, in ascending order."""
    return sorted({int(c) for c in (*COMMAND_CODES[command], *ALWAYS)})


def exit_codes_epilog(command: str) -> str:
    """The "exit codes:" block that ends ``edc-bench COMMAND --help``, one line per code."""
    lines = ["exit codes:"]
    for code in command_codes(command):
        meaning = SUCCESS.get(command, "done") if code == 0 else MEANINGS[code]
        lines.append(f"  {code:>3}  {meaning}")
    return "\n".join(lines)


def exit_codes_sentence() -> str:
    """README's one-line summary: ``Exit codes: 0 PASS, 10 MARGINAL, ..., 130 interrupted.``

    The outcomes first (0, then 10 and up), then the codes that say the command could not do its job.
    """
    codes = sorted({int(c) for c in ExitCode}, key=lambda c: (not (c == 0 or 10 <= c < 70), c))
    return "Exit codes: " + ", ".join(f"{c} {SHORT_NAMES[c]}" for c in codes) + "."
