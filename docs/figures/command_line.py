"""The figures of docs/command-line.md: what ``edc-bench`` accepts, prints and returns, from the CLI's own code.

Everything here is live (the parser and its constants, no test is run): the identity rule with an example
refusal as the command prints it, and each command's exit codes.
"""

from __future__ import annotations

import contextlib
import io
import tempfile
from pathlib import Path

from figures.common import table

#: A valve id as a technician might type it: a slash and brackets, kept as typed, cleaned in the folder's name.
ODD_ID = "V/7 [a]"

#: A valve id with a line break pasted in: refused.
PASTED_ID = "V-7\n"


def cli_stderr(argv: list[str]) -> tuple[int, str]:
    """Run ``edc-bench ARGV`` in process; return its exit code and what it printed on stderr.

    Only for command lines refused before any work (argparse's checks): nothing else is run.
    """
    from edc_bench.cli import main

    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        try:
            code = main(argv)
        except SystemExit as exc:
            code = exc.code if isinstance(exc.code, int) else 1
    return code, err.getvalue().rstrip("\n")


def record_folder_suffix(valve_id: str) -> str:
    """The end of the record folder's name a test of ``valve_id`` gets (``..._V_7_a``), made in a scratch folder."""
    from edc_bench.records.writer import new_record_dir

    variant = "p-edc-default"
    with tempfile.TemporaryDirectory() as scratch:
        name = new_record_dir(Path(scratch), valve_id, variant, "2026-01-01T00:00:00+00:00").name
    return name.split(f"-{variant}-", 1)[1]


def identities_bullet() -> str:
    """The bullet on identities: their limit, what is kept as given, the folder's cleaned name, a refusal."""
    from edc_bench.cli.common import MAX_ID_CHARS

    code, message = cli_stderr(["test", "--valve-id", PASTED_ID])
    if code != 2:
        raise RuntimeError(f"a pasted line break in --valve-id gave exit {code}, not 2: {message}")
    for command in ("test", "calibrate"):  # the sentence says '$' is accepted by both
        parsed = _parse([command, "--valve-id", "V$7$"])
        if parsed.valve_id != "V$7$":
            raise RuntimeError(f"{command} no longer keeps a '$' in --valve-id")
    return (f"- **Identities** (`--valve-id`, `--pump-serial`, `--operator`, `--station`,\n"
            f"  `label VALVE_ID`, `--by`): at most {MAX_ID_CHARS} characters of valid text (bytes\n"
            f"  typed in another encoding than the terminal's UTF-8 are refused), no\n"
            f"  control characters. Anything else is kept exactly as given, brackets,\n"
            f"  quotes, slashes, `$` and all, in the record and the history; only the record\n"
            f"  folder's name is cleaned (`{ODD_ID}` becomes `..._{record_folder_suffix(ODD_ID)}`). The record's figure\n"
            f"  and the report draw the identity as typed (matplotlib does not read\n"
            f"  `$...$` in it as a formula). A line break pasted with an id is refused, for example:\n"
            f"\n"
            f"  ```text\n"
            f"  {message}\n"
            f"  ```")


def _parse(argv: list[str]):
    """``edc-bench ARGV`` parsed, not run."""
    from edc_bench.cli import build_parser

    return build_parser().parse_args(argv)


def exit_meanings_table() -> str:
    """What each exit code means (``edc_bench/cli/exit_codes.py``'s MEANINGS)."""
    from edc_bench.cli.exit_codes import MEANINGS

    return table(("code", "meaning"), [(f"`{int(code)}`", meaning) for code, meaning in MEANINGS.items()])


def exit_codes_table() -> str:
    """Each command and the exit codes it can return (as its ``--help`` lists them)."""
    from edc_bench.cli.exit_codes import COMMAND_CODES, command_codes

    rows = [(f"`{name}`", ", ".join(str(code) for code in command_codes(name))) for name in COMMAND_CODES]
    return table(("command", "exit codes"), rows)
