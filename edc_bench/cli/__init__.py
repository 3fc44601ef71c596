"""The ``edc-bench`` command line: one module per command.

Each command module defines ``add_parser(subparsers)`` and ``run(args) -> int``
and imports what it needs inside ``run``, so ``edc-bench --help`` stays fast.
Errors raised on purpose (:class:`~edc_bench.errors.EdcBenchError`) become one
clear line; anything else is an internal error with its own exit code.
"""

from __future__ import annotations

import argparse
import errno
import importlib
import sys
from collections.abc import Sequence

from edc_bench.cli.exit_codes import ExitCode

COMMANDS = ("test", "rig", "variants", "tune", "calibrate", "train", "classify", "evaluate", "paper", "study-boundary",
            "perf", "replay", "history", "label", "report", "check-station", "rig-check", "session",
            "rig-selfcheck", "web")


def build_parser() -> argparse.ArgumentParser:
    """The top-level parser with every command's subparser."""
    from edc_bench import __version__
    from edc_bench.cli.common import ArgumentParser
    from edc_bench.cli.exit_codes import exit_codes_epilog

    parser = ArgumentParser(
        prog="edc-bench",
        description="Bench diagnosis of P-EDC solenoid valves over CAN.",
        epilog="Every command's --help ends with the exit codes it can return (docs/command-line.md says what each means).",
    )
    parser.add_argument("--version", action="version", version=f"edc-bench {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for name in COMMANDS:
        importlib.import_module(f"edc_bench.cli.{name.replace('-', '_')}_cmd").add_parser(sub)
        # built here from exit_codes.py, so no command's help can drift from the codes it returns
        sub.choices[name].epilog = exit_codes_epilog(name)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``edc-bench``; returns the process exit code."""
    argv = sys.argv[1:] if argv is None else list(argv)
    _hide_history_passwords(argv)  # before parsing: argparse's errors quote the arguments
    from edc_bench.runtime.signals import raise_on_interrupt

    try:
        with raise_on_interrupt():  # SIGTERM means what Ctrl-C means, from here to the exit code
            return _run(build_parser().parse_args(argv))
    except KeyboardInterrupt:  # before the command could start: while the parser imports the commands
        print("edc-bench: interrupted", file=sys.stderr)
        return ExitCode.INTERRUPTED
    finally:
        _flush_redacting_streams()


def _run(args: argparse.Namespace) -> int:
    """Run the parsed command; an error raised on purpose becomes one line and its exit code."""
    from edc_bench.cli.common import printable
    from edc_bench.errors import EdcBenchError, RecordNotWrittenError, RigError

    from edc_bench.runtime.signals import interrupt_raised

    try:
        code = int(args.run(args))
        if code == ExitCode.OK and interrupt_raised():  # a Ctrl-C Python swallowed, the command done all the same:
            print(f"edc-bench {args.command}: interrupted", file=sys.stderr)  # still Ctrl-C
            return ExitCode.INTERRUPTED
        return code
    except RigError as exc:
        print(printable(f"edc-bench {args.command}: error: {exc}"), file=sys.stderr)
        return ExitCode.RIG_ERROR
    except RecordNotWrittenError as exc:
        print(printable(f"edc-bench {args.command}: error: {exc}"), file=sys.stderr)
        return ExitCode.RECORD_NOT_WRITTEN
    except EdcBenchError as exc:
        print(printable(f"edc-bench {args.command}: error: {exc}"), file=sys.stderr)
        return ExitCode.BAD_INPUT
    except KeyboardInterrupt:
        print(f"edc-bench {args.command}: interrupted", file=sys.stderr)
        return ExitCode.INTERRUPTED
    except BrokenPipeError:
        # the reader went away (`edc-bench ... | head`): nothing left to say to it
        import os

        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return ExitCode.OK
    except OSError as exc:
        message = path_problem(exc)
        if message is None and exc.errno in _NO_ROOM:  # a write into a full disk names no file (os.write, fsync)
            message = f"{exc.strerror or 'no space left'}: {_PATH_ADVICE[exc.errno]}"
        if message is None:
            return _internal_error(args.command, exc)
        print(printable(f"edc-bench {args.command}: error: {message}"), file=sys.stderr)
        return ExitCode.RECORD_NOT_WRITTEN if exc.errno in _NO_ROOM else ExitCode.BAD_INPUT
    except Exception as exc:  # noqa: BLE001 - the last line of defence for the technician
        if interrupt_raised():  # a library cut short by Ctrl-C may say so in an error of its own: still Ctrl-C
            print(f"edc-bench {args.command}: interrupted", file=sys.stderr)
            return ExitCode.INTERRUPTED
        return _internal_error(args.command, exc)


def _hide_history_passwords(argv: Sequence[str]) -> None:
    """While a history password is known (in the arguments, such as ``--db URL``, or ``EDC_BENCH_HISTORY_URL``),
    nothing this process prints can show it: every URL edc-bench prints is masked where it is made, and standard
    output and error are scrubbed too (:class:`~edc_bench.history.secrets.RedactingStream`), for what argparse
    quotes of the arguments and what a library prints (a driver's message, a traceback)."""
    from edc_bench.history.secrets import RedactingStream, known_secrets

    secrets = known_secrets(*argv)  # every argument: a mistyped flag's URL is quoted as much as --db's
    if secrets:
        sys.stdout = RedactingStream(sys.stdout, secrets)  # type: ignore[assignment]
        sys.stderr = RedactingStream(sys.stderr, secrets)  # type: ignore[assignment]


def _flush_redacting_streams() -> None:
    """Write out the line a :class:`~edc_bench.history.secrets.RedactingStream` holds unended (``print(...,
    end="")``), for a caller that goes on in this process; a reader gone by now is no error."""
    from edc_bench.history.secrets import RedactingStream

    for stream in (sys.stdout, sys.stderr):
        if isinstance(stream, RedactingStream):
            try:
                stream.flush()
            except (OSError, ValueError):  # a closed pipe, a closed file
                pass


_NO_ROOM = (errno.ENOSPC, errno.EDQUOT)
#: what to do about a path the system refused, by errno
_PATH_ADVICE = {
    errno.ENAMETOOLONG: "the path or one of its names is too long: give a shorter one",
    errno.EACCES: "not allowed: give a path this user may use",
    errno.EPERM: "not allowed (an immutable or protected file): give another path",
    errno.EEXIST: "something is already there: give another path",
    errno.ENOTDIR: "a part of the path is a file, not a folder: check the path",
    errno.EISDIR: "it is a folder: give a file",
    errno.ELOOP: "the path loops through symbolic links: check it",
    errno.EROFS: "the file system is read-only: give a path on a writable one",
    errno.ENOENT: "no such file or folder: check the path",
    errno.ENOSPC: "the disk is full: free space, then run it again",
    errno.EDQUOT: "the disk quota is used up: free space, then run it again",
}


def path_problem(exc: OSError) -> str | None:
    """One line for an OSError on a path the user gave (or the environment named); None for any other OSError.

    Every command checks its paths before it works; this is the net under those checks, for what the system
    refuses in ways no check foresaw (a name too long, an immutable file, a data folder that is a file).
    """
    if exc.filename is None or exc.errno not in _PATH_ADVICE:
        return None
    target = f"{exc.filename}" + (f" -> {exc.filename2}" if exc.filename2 else "")
    return f"{target}: {exc.strerror}: {_PATH_ADVICE[exc.errno]}"


def _internal_error(command: str, exc: BaseException) -> int:
    """A bug: say so, with the traceback that helps to fix it."""
    import traceback

    from edc_bench.cli.common import printable

    print(printable(f"edc-bench {command}: internal error: {type(exc).__name__}: {exc}\n"
                    "This is a bug in edc-bench; the details below help to fix it."), file=sys.stderr)
    traceback.print_exception(exc, file=sys.stderr)
    return ExitCode.INTERNAL_ERROR
