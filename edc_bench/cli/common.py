"""Arguments shared by several commands."""

from __future__ import annotations

import argparse
from collections.abc import Callable
from pathlib import Path
from typing import Any


def add_variant_arguments(parser: argparse.ArgumentParser) -> None:
    """``--variant`` and ``--valve`` as every rig-related command takes them."""
    parser.add_argument("--variant", default=None, metavar="NAME|PART|PATH",
                        help="pump variant: a name from 'edc-bench variants', a part number or a .toml file "
                             "(default: p-edc-default)")
    parser.add_argument("--valve", default="new", metavar="SPEC",
                        help="simulated valve: new, worn, faulty, or physical values such as "
                             "clearance=0.22,roughness=1.5 (default: new)")


def add_population_arguments(parser: argparse.ArgumentParser, count: int, seed: int) -> None:
    """``--variants``, ``--count``, ``--seed`` and ``--model`` for commands that judge a simulated population."""
    from pathlib import Path

    parser.add_argument("--variants", nargs="+", default=["p-edc-default", "p-edc-long"], metavar="NAME",
                        help="variants to draw valves for (default: p-edc-default p-edc-long)")
    parser.add_argument("--count", type=int, default=count, help=f"valves per variant (default: {count})")
    parser.add_argument("--seed", type=int, default=seed,
                        help=f"population seed (default: {seed}; the shipped models were trained with 2026)")
    parser.add_argument("--model", type=Path, default=None,
                        help="ONNX model (default: the station's: the adopted one, else the packaged network)")


def print_quietly_if_closed(write: Callable[[], None]) -> None:
    """Run ``write`` (prints to stdout); if the reader has gone (``| head``), stop printing quietly.

    Commands whose exit code carries a verdict call this so the code survives a closed pipe.
    """
    import os
    import sys

    try:
        write()
        sys.stdout.flush()
    except BrokenPipeError:
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())


def parse_host_port(text: str) -> tuple[str, int]:
    """Parse ``HOST:PORT`` for argparse, with a clear message."""
    host, sep, port = text.rpartition(":")
    if not sep or not host:
        raise argparse.ArgumentTypeError(f"expected HOST:PORT such as 127.0.0.1:5000, got {text!r}")
    try:
        number = int(port)
    except ValueError:
        raise argparse.ArgumentTypeError(f"port {port!r} is not a number") from None
    if not 0 <= number <= 65535:
        raise argparse.ArgumentTypeError(f"port {number} is outside 0..65535")
    return host, number


def check_output_folder(folder: Path, flag: str) -> None:
    """Refuse an output folder that is a file or cannot be made or written, before any work starts.

    Raises
    ------
    ConfigError
        Naming the flag, the folder and what to do.
    """
    import os

    from edc_bench.errors import ConfigError

    if folder.exists() and not folder.is_dir():
        raise ConfigError(f"{flag} {folder}: is a file, not a folder; give a folder for the records")
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ConfigError(f"{flag} {folder}: cannot make the folder ({exc.strerror or exc}); give a writable "
                          "folder") from None
    if not os.access(folder, os.W_OK | os.X_OK):
        raise ConfigError(f"{flag} {folder}: the folder is not writable; give a writable folder")


def add_history_db_argument(parser: Any, when: str = "") -> None:
    """``--db URL``: the history database, as every command that reads or writes the history takes it."""
    parser.add_argument("--db", default=None, metavar="URL",
                        help=f"{when}history database: sqlite:///FILE or postgresql+psycopg://USER@HOST/DB "
                             "(default: EDC_BENCH_HISTORY_URL, else the station's SQLite file)")


def add_history_label_arguments(parser: argparse.ArgumentParser) -> None:
    """``--from-history`` and ``--db``: judge the shop's labelled tests instead of a simulated population."""
    parser.add_argument("--from-history", action="store_true",
                        help="use the history's labelled tests (teardown findings, 'edc-bench label') instead of "
                             "simulating a population")
    add_history_db_argument(parser, "with --from-history: ")


def history_label_dataset(url: str | None) -> tuple[object, str]:
    """The history's labelled tests as a dataset, and a description of where they came from."""
    from edc_bench.errors import ConfigError
    from edc_bench.history.labels import labelled_tests
    from edc_bench.history.store import HistoryStore

    with HistoryStore(url) as store:
        labelled = labelled_tests(store)
        where = store.engine.url.render_as_string(hide_password=True)
    if len(labelled) == 0:
        raise ConfigError(f"no labelled test in {where}: record teardown findings with 'edc-bench label' first")
    dataset = labelled.as_dataset({"history": where, "labels": len(labelled)})
    return dataset, f"{len(labelled)} labelled tests in {where}"
