"""Arguments shared by several commands, and the checks every command makes of its input before any work.

The same thing has the same flag in every command (docs/command-line.md):
``--variant``, ``--valve SPEC`` (a simulated valve), ``--valve-id ID`` (the
valve's identity), ``--db URL`` (the history), ``--seed N``, ``--out DIR`` (a
folder the command writes into) and ``--<what>-file FILE`` / ``--figure`` /
``--plot`` / ``--csv`` (one file). Old spellings stay as hidden aliases.
"""

from __future__ import annotations

import argparse
import math
import unicodedata
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any, NoReturn

if TYPE_CHECKING:
    from edc_bench.runtime.bus_config import BusSettings

#: The longest identity (valve id, pump serial, operator, station) a record takes: a record folder's name
#: holds the valve id, and folder names stop at 255 bytes.
MAX_ID_CHARS = 100

#: The largest seed (numpy's legacy generators take 32 bits).
MAX_SEED = 2**31 - 1  # seeds of runs and population members count up from it, within numpy's and sklearn's 2**32


class HelpFormatter(argparse.HelpFormatter):
    """argparse's formatter, but a text with line breaks (the exit-code epilog) keeps them."""

    def _fill_text(self, text: str, width: int, indent: str) -> str:
        if "\n" in text:
            return "\n".join(indent + line for line in text.splitlines())
        return super()._fill_text(text, width, indent)


class ArgumentParser(argparse.ArgumentParser):
    """argparse's parser, saying a usage error in one line that names the flag and points at ``--help``."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        kwargs.setdefault("formatter_class", HelpFormatter)
        super().__init__(*args, **kwargs)

    def error(self, message: str) -> NoReturn:
        """Print one line (no usage block) and exit with 2, as every refused input does."""
        self.exit(2, printable(f"{self.prog}: error: {message} (see '{self.prog} --help')\n"))


def printable(text: str) -> str:
    """``text`` safe to print on any stream: text that is not valid Unicode (bytes of a non-UTF-8 argument) escaped."""
    return text.encode("utf-8", "backslashreplace").decode("utf-8")


def add_hidden_alias(parser: Any, old: str, dest: str, **kwargs: Any) -> None:
    """An old spelling of a flag that keeps scripts working but is left out of ``--help``."""
    parser.add_argument(old, dest=dest, help=argparse.SUPPRESS, default=argparse.SUPPRESS, **kwargs)


# -- argparse types: each names what was wrong and what to give instead ------------------------------------------


def given_path(text: str) -> Path:
    """A file or folder flag's path: refused empty (``--out ''`` would be the current folder, unsaid)."""
    if not text.strip():
        raise argparse.ArgumentTypeError("an empty path: give a file or folder name ('.' for the current folder)")
    return Path(text)


def given_path_text(text: str) -> str:
    """A file flag's value kept as text (``-`` for standard output, ``shipped``): refused empty (it would be taken
    for the current folder)."""
    if not text.strip():
        raise argparse.ArgumentTypeError("an empty path: give a file name")
    return text


def history_url(text: str) -> str:
    """``--db URL``: refused empty (``--db ''`` would be the default history, unsaid)."""
    if not text.strip():
        raise argparse.ArgumentTypeError("an empty URL: give sqlite:///FILE or postgresql+psycopg://USER@HOST/DB, "
                                         "or leave --db out for the default history")
    return text


def seed_number(text: str) -> int:
    """``--seed``: a whole number from 0 to :data:`MAX_SEED`."""
    try:
        value = int(text)
    except ValueError:
        value = -1
    if not 0 <= value <= MAX_SEED:
        raise argparse.ArgumentTypeError(f"{text!r} is not a seed: give a whole number, 0 or more "
                                         f"(at most {MAX_SEED})")
    return value


def positive_int(text: str) -> int:
    """A count or an id: a whole number, 1 or more (at most 2**63 - 1, what a database stores)."""
    return count_up_to(2**63 - 1)(text)


def count_up_to(limit: int, why: str = "") -> Callable[[str], int]:
    """An argparse type: a whole number from 1 to ``limit`` (``why`` says what the limit stands for)."""
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not a whole number: give 1 or more") from None
        if value < 1:
            raise argparse.ArgumentTypeError(f"{value} is not a count: give 1 or more")
        if value > limit:
            raise argparse.ArgumentTypeError(f"{value} is too many: at most {limit}{why}")
        return value
    return parse


def port_number(text: str) -> int:
    """A TCP port: a whole number from 1 to 65535."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a port number: give a whole number from 1 to 65535") from None
    if not 1 <= value <= 65535:
        raise argparse.ArgumentTypeError(f"{value} is not a port number: give one from 1 to 65535")
    return value


#: the modules each optional extra (pyproject.toml's [project.optional-dependencies]) brings, by the name pip knows
#: each one's package by
EXTRAS = {"train": {"sklearn": "scikit-learn", "skl2onnx": "skl2onnx", "onnx": "onnx"}}


def require_extra(extra: str, what: str) -> None:
    """Refuse, before any work, a command that needs an extra this install lacks: one line naming the extra.

    Parameters
    ----------
    extra : str
        A key of :data:`EXTRAS`.
    what : str
        What needs it, as the line says it ("training", "the paper's experiment").
    """
    import importlib.util

    missing = [package for module, package in EXTRAS[extra].items() if importlib.util.find_spec(module) is None]
    if missing:
        from edc_bench.errors import ConfigError

        raise ConfigError(f"{what} needs the '{extra}' extra ({', '.join(missing)} not installed): pip install "
                          f"'edc-bench[{extra}]' (in a clone of the repository: pip install '.[{extra}]')")


#: valves a simulated population may have per variant (a run of the largest takes hours)
MAX_POPULATION = 20_000


def bit_rate(text: str) -> int:
    """``--bitrate``: a classic CAN bit rate, 10 kbit/s to 1 Mbit/s."""
    try:
        value = int(text)
    except ValueError:
        value = 0
    if not 10_000 <= value <= 1_000_000:
        raise argparse.ArgumentTypeError(f"{text!r} is not a CAN bit rate: give bits per second, 10000 to 1000000 "
                                         "(the ICD's is 500000)")
    return value


def finite_float(text: str, what: str) -> float:
    """``text`` as a finite number, or an argparse error naming ``what`` is expected."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number: give {what}") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"{text!r} is not a finite number: give {what}")
    return value


def positive_float(what: str) -> Callable[[str], float]:
    """An argparse type: a finite number above 0 (``what`` says which, with its unit and an example)."""
    def parse(text: str) -> float:
        value = finite_float(text, what)
        if value <= 0:
            raise argparse.ArgumentTypeError(f"{text} is not above 0: give {what}")
        return value
    return parse


def identity(limit: int = MAX_ID_CHARS) -> Callable[[str], str]:
    """An argparse type for an identity (valve id, pump serial, operator, station): valid text, at most ``limit``."""
    def parse(text: str) -> str:
        # given and empty is as blank as spaces: a flag left out is how to give none
        problem = "is empty: give it as printed on the part, or leave the flag out" if text == "" else \
            text_problem(text, limit)
        if problem:
            shown = text if len(text) <= 60 else f"{text[:57]}..."  # a long one cut before quoting: quotes closed
            raise argparse.ArgumentTypeError(f"{printable(repr(shown))} {problem}")
        return text
    return parse


def text_problem(text: str, limit: int, lines: bool = False) -> str | None:
    """Why ``text`` cannot be kept in a record and the history, or None.

    Text that is not valid Unicode (an argument in another encoding than the
    terminal's UTF-8), control characters (a line break pasted with an id)
    and anything longer than ``limit`` are refused; everything else, odd or
    not, is kept exactly as given.
    """
    try:
        text.encode("utf-8")
    except UnicodeEncodeError:
        return "is not valid UTF-8 text (typed in another encoding?): type it again in a UTF-8 terminal"
    if text and not text.strip():  # empty is "not given" (the flags' default)
        return "is blank: give the id as printed on the part"
    if len(text) > limit:
        return f"is {len(text)} characters long: at most {limit}"
    allowed = "\n\t" if lines else ""
    # control characters and line breaks only: a no-break space pasted from a spreadsheet is odd, but text
    if any(unicodedata.category(c) in ("Cc", "Zl", "Zp") and c not in allowed for c in text):
        return "contains a control character (a line break, tab or escape): give it on one line, as printed"
    # invisible format characters (zero-width space, right-to-left override) make two ids look alike
    if any(unicodedata.category(c) == "Cf" for c in text):
        return "contains an invisible character (zero-width or text-direction): type it again, as printed"
    return None


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
    parser.add_argument("--count", type=count_up_to(MAX_POPULATION, " valves per variant (that many take hours)"),
                        default=count, help=f"valves per variant (default: {count}; at most {MAX_POPULATION})")
    parser.add_argument("--seed", type=seed_number, default=seed,
                        help=f"population seed (default: {seed}; the shipped models were trained with 2026)")
    parser.add_argument("--model", type=given_path, default=None,
                        help="ONNX model (default: the variant's own if its [diagnosis] model names one, else the "
                        "station's: the adopted one, else the packaged network)")


def check_population_inputs(args: argparse.Namespace) -> None:
    """Load every ``--variants`` name and the ``--model`` before a population is simulated (minutes of work)."""
    from edc_bench.config import load_variant

    for name in args.variants:
        load_variant(name)
    if args.model is not None:
        from edc_bench.verdict.classifier import ValveClassifier

        ValveClassifier(args.model)
    else:  # each variant's own model, if its file names one: present?
        from edc_bench.verdict.classifier import variant_model_path

        for name in args.variants:
            variant_model_path(load_variant(name))


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
    """Refuse an output folder that is a file or a device, or cannot be made or written, before any work starts.

    A folder that does not exist yet is made (``--out records`` on a fresh station).

    Raises
    ------
    ConfigError
        Naming the flag, the folder and what to do.
    """
    from edc_bench.errors import ConfigError

    if folder.exists() and not folder.is_dir():
        kind = "a file" if folder.is_file() else "a device or other special file"
        raise ConfigError(f"{flag} {folder}: is {kind}, not a folder; give a folder (made if missing)")
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ConfigError(f"{flag} {folder}: cannot make the folder ({exc.strerror or exc}); give a writable "
                          "folder") from None
    probe_writable(folder, f"{flag} {folder}: the folder is not writable")


def check_output_file(path: Path, flag: str, suffix: str | None = None) -> None:
    """Refuse an output file before any work starts: a folder, a device, a missing or unwritable folder, a wrong suffix.

    Parameters
    ----------
    path : pathlib.Path
        The file the command will write (replaced if it exists).
    flag : str
        The flag that named it, for the message.
    suffix : str, optional
        The suffix the file must have (``".png"``: the figures are PNG whatever the name says).

    Raises
    ------
    ConfigError
        Naming the flag, the path and what to give instead.
    """
    from edc_bench.errors import ConfigError

    if path.is_dir():
        raise ConfigError(f"{flag} {path}: is a folder; give a file name such as {path / ('out' + (suffix or ''))}")
    if path.exists() and not path.is_file():
        raise ConfigError(f"{flag} {path}: is a device or other special file, not a file; give a file name")
    if suffix is not None and path.suffix.lower() != suffix:
        raise ConfigError(f"{flag} {path}: the file is {suffix[1:].upper()}; give a name ending in {suffix}")
    folder = path.parent
    if not folder.is_dir():
        raise ConfigError(f"{flag} {path}: the folder {folder} does not exist; make it first (mkdir -p {folder}) "
                          "or give another place")
    probe_writable(folder, f"{flag} {path}: its folder {folder} is not writable; give another place")


def probe_writable(folder: Path, message: str) -> None:
    """Write and remove a scratch file in ``folder``: the one test of writability that holds for root too."""
    import tempfile

    from edc_bench.errors import ConfigError

    try:
        with tempfile.TemporaryFile(dir=folder):
            pass
    except OSError as exc:
        raise ConfigError(f"{message} ({exc.strerror or exc})") from None


def bus_option(text: str) -> tuple[str, str]:
    """``--bus-option KEY=VALUE``: one further argument of the python-can interface (socketcand's ``host``...)."""
    key, sep, value = text.partition("=")
    key = key.strip()
    if not sep or not key.isidentifier():
        raise argparse.ArgumentTypeError(f"{text!r} is not KEY=VALUE: give one argument of the python-can interface, "
                                         "e.g. --bus-option host=192.168.1.10")
    if key in ("interface", "bustype", "channel", "bitrate"):
        flag = "interface" if key == "bustype" else key
        raise argparse.ArgumentTypeError(f"{key} has a flag of its own: give --{flag} {value or flag.upper()}")
    return key, value


def add_bus_arguments(parser: Any, interface_help: str = "python-can interface, e.g. slcan, socketcan, pcan",
                      channel_help: str = "python-can channel, e.g. socket://127.0.0.1:5000 or can0",
                      bitrate_help: str = "CAN bit rate (default: the ICD's 500000)") -> None:
    """``--interface``, ``--channel``, ``--bitrate`` and ``--bus-option``: a python-can bus, as every command on a
    rig takes it (:func:`bus_settings` checks them)."""
    parser.add_argument("--interface", default=None, help=interface_help)
    parser.add_argument("--channel", default=None, help=channel_help)
    parser.add_argument("--bitrate", type=bit_rate, default=None, help=bitrate_help)
    parser.add_argument("--bus-option", dest="bus_options", type=bus_option, action="append", default=[],
                        metavar="KEY=VALUE",
                        help="a further argument of the python-can interface, repeatable, e.g. --bus-option "
                             "host=192.168.1.10 --bus-option port=29536 for socketcand; values are read as python-can "
                             "reads its config file (5 is a number, true a yes). CAN_CONFIG (a JSON object) and "
                             "python-can's config file can give them too")


def bus_settings(interface: str | None, channel: str | None, bitrate: int | None, *,
                 configured_alone: bool, options: list[tuple[str, str]] | None = None) -> BusSettings | None:
    """The python-can bus to open, checked before any work; None for no bus (the simulated rig).

    The flags win; what they leave open comes from python-can's own sources
    (``CAN_INTERFACE``/``CAN_CHANNEL``/``CAN_BITRATE``/``CAN_CONFIG``, then its config files, each read in the
    encoding it was written in: :mod:`edc_bench.runtime.bus_config`), further arguments included. The
    interface's module is loaded and the arguments its bus requires are checked here, before any work: a
    driver that cannot load or a channel or host not given is one line, exit 3.

    Parameters
    ----------
    interface, channel, bitrate
        The ``--interface``, ``--channel`` and ``--bitrate`` flags (None: not given).
    configured_alone : bool
        Whether python-can's environment or config file alone selects a bus (``test`` does; ``calibrate``
        takes a bus from its flags only, and the environment only completes them). Without flags and without
        it, python-can's sources are not read at all.
    options : list of (str, str), optional
        The ``--bus-option KEY=VALUE`` flags.

    Returns
    -------
    BusSettings or None
        A dict of python-can's bus arguments (text as given; :func:`~edc_bench.runtime.bus.open_bus` casts
        them as python-can does), knowing where those no flag gave came from.

    Raises
    ------
    ConfigError
        An interface python-can does not have, a channel or option without an interface, an option given
        twice, a bit rate that is not a number: naming the setting and listing what python-can accepts.
    RigError
        A config file or ``CAN_CONFIG`` that cannot be read (naming it); an interface that cannot load here or
        lacks a channel or argument it requires (naming what to install or give).
    """
    from edc_bench.canlib import can
    from edc_bench.errors import ConfigError
    from edc_bench.runtime.bus_config import ENVIRONMENT, BusSettings, check_interface, python_can_config

    options = list(options or [])
    given = dict(options)
    if len(given) < len(options):
        twice = next(key for key in given if sum(k == key for k, _ in options) > 1)
        raise ConfigError(f"--bus-option {twice} is given twice: give each argument once")
    flags = {k: v for k, v in (("interface", interface), ("channel", channel), ("bitrate", bitrate)) if v is not None}
    if not flags and not given and not configured_alone:
        return None
    configured, sources = python_can_config()
    if not flags and not given and not configured.get("interface"):
        return None
    if "interface" not in flags and "channel" not in flags and not configured.get("interface") and (
            "bitrate" in flags or given):
        what = f"--bitrate {bitrate} sets the bit rate of a bus" if "bitrate" in flags else \
            f"--bus-option {next(iter(given))} is an argument of a bus"
        raise ConfigError(f"{what}: give --interface and --channel too (the simulated rig has no bus)")
    named = ("interface", "channel", "bitrate")  # first, for messages that show the settings
    merged = {**{k: v for k, v in configured.items() if k not in named or v}, **given, **flags}
    settings = {**{k: merged[k] for k in named if k in merged}, **{k: v for k, v in merged.items() if k not in named}}
    origin = {k: sources[k] for k in settings if k not in flags and k not in given and k in sources}

    def source(key: str) -> str:
        """The flag, variable or file that gave ``key``, for a message."""
        if key in flags or key in given:
            return f"--{key}" if key in flags else f"--bus-option {key}"
        where = origin.get(key, "")
        return where if where in ENVIRONMENT.values() else f"{key} in {where}" if where else key

    valid = sorted(can.interfaces.VALID_INTERFACES)
    if not settings.get("interface"):
        what = (f"--channel {channel} needs --interface" if channel is not None else
                "--interface is empty" if interface is not None else
                f"{source('channel')} needs an interface" if settings.get("channel") else
                "the bus options need an interface")
        raise ConfigError(f"{what}: give the python-can interface of the adapter, one of "
                          f"{', '.join(valid)} (e.g. --interface socketcan --channel can0, or --interface slcan "
                          "--channel socket://127.0.0.1:5000); or set CAN_INTERFACE")
    if not isinstance(settings["interface"], str) or settings["interface"] not in can.interfaces.VALID_INTERFACES:
        raise ConfigError(f"{source('interface')} {settings['interface']!r}: python-can has no such interface; use "
                          f"one of {', '.join(valid)}")
    if "bitrate" in settings:
        try:
            settings["bitrate"] = int(settings["bitrate"])
        except (TypeError, ValueError):
            raise ConfigError(f"{source('bitrate')} {settings['bitrate']!r}: not a bit rate; give bits per second, "
                              "e.g. 500000") from None
        if settings["bitrate"] <= 0:
            raise ConfigError(f"{source('bitrate')} {settings['bitrate']}: give bits per second above 0, e.g. 500000")
    by_source: dict[str, list[str]] = {}
    for key, where in origin.items():
        by_source.setdefault(where, []).append(key)
    bus = BusSettings(settings, "; ".join(f"{', '.join(keys)} from {where}" for where, keys in by_source.items()))
    check_interface(bus)
    return bus


def check_history_url(url: str | None) -> None:
    """Refuse a history database that cannot be right before any work (see :func:`edc_bench.history.url.check_url`)."""
    from edc_bench.history.url import check_url

    check_url(url)


def add_history_db_argument(parser: Any, when: str = "", dest: str = "db") -> None:
    """``--db URL``: the history database, as every command that reads or writes the history takes it.

    ``--history-db`` (what ``test`` called it before) stays as a hidden alias.
    """
    parser.add_argument("--db", dest=dest, default=None, metavar="URL", type=history_url,
                        help=f"{when}history database: sqlite:///FILE or postgresql+psycopg://USER@HOST/DB "
                             "(default: EDC_BENCH_HISTORY_URL, else the station's SQLite file)")
    add_hidden_alias(parser, "--history-db", dest, type=history_url)


def add_history_label_arguments(parser: argparse.ArgumentParser) -> None:
    """``--from-history`` and ``--db``: judge the shop's labelled tests instead of a simulated population."""
    parser.add_argument("--from-history", action="store_true",
                        help="use the history's labelled tests (teardown findings, 'edc-bench label') instead of "
                             "simulating a population")
    add_history_db_argument(parser, "with --from-history: ")
    add_include_simulated_argument(parser)


def add_include_simulated_argument(parser: Any, what: str = "with --from-history: learn from") -> None:
    """``--include-simulated``: count the tests run on the simulated rig, which the history leaves out of trends
    and training."""
    parser.add_argument("--include-simulated", action="store_true",
                        help=f"{what} tests run on the simulated rig too (left out by default)")


def history_label_dataset(url: str | None, include_simulated: bool = False) -> tuple[object, str]:
    """The history's labelled tests as a dataset, and a description of where they came from."""
    from edc_bench.errors import ConfigError
    from edc_bench.history.labels import labelled_tests
    from edc_bench.history.store import HistoryStore

    with HistoryStore(url, must_exist=True) as store:
        labelled = labelled_tests(store, include_simulated)
        where = store.shown_url
    if len(labelled) == 0:
        raise ConfigError(f"no labelled test in {where}: record teardown findings with 'edc-bench label' first")
    dataset = labelled.as_dataset({"history": where, "labels": len(labelled)})
    return dataset, f"{len(labelled)} labelled tests in {where}"


def person_name(given: str | None, what: str) -> str:
    """``--by``, checked (default: the login name)."""
    import getpass

    from edc_bench.errors import ConfigError

    by = (given if given is not None else getpass.getuser()).strip()
    problem = "is empty" if not by else text_problem(by, MAX_ID_CHARS)
    if problem:
        raise ConfigError(f"--by {given!r} {problem}; give {what}")
    return by


def rig_drift(text: str) -> Any:
    """``--rig-drift``: the simulated rig's sensor drift (:func:`edc_bench.sim.drift.parse_rig_drift`)."""
    from edc_bench.errors import ConfigError
    from edc_bench.sim.drift import parse_rig_drift

    try:
        return parse_rig_drift(text, flag="")
    except ConfigError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def add_rig_drift_argument(parser: Any) -> None:
    """``--rig-drift SPEC``: the simulated rig's sensors drifted, as every command that runs the simulated rig
    takes it."""
    parser.add_argument("--rig-drift", type=rig_drift, default=None, metavar="SPEC",
                        help="simulated rig: its sensors drifted, e.g. lvdt_offset_mm=0.05 or current_gain=1.03 "
                             "(keys lvdt_offset_mm, lvdt_gain, current_gain, current_offset_a; default: none), what "
                             "'edc-bench rig-selfcheck' must catch")


def _fault_type(parse: Any) -> Any:
    def convert(text: str) -> Any:
        from edc_bench.errors import ConfigError

        try:
            return parse(text, flag="")
        except ConfigError as exc:
            raise argparse.ArgumentTypeError(str(exc)) from None
    return convert


def add_pump_fault_arguments(parser: Any) -> None:
    """``--rack-fault SPEC`` and ``--sensor-fault SPEC``: the simulated pump's control rack binds or drags, its
    rack-travel sensor misreads (:mod:`edc_bench.sim.pump_faults`), as every command that runs the simulated rig
    takes them."""
    from edc_bench.sim.pump_faults import (
        RACK_KEYS,
        RACK_PRESETS,
        SENSOR_KEYS,
        SENSOR_PRESETS,
        parse_rack_fault,
        parse_sensor_fault,
    )

    parser.add_argument("--rack-fault", type=_fault_type(parse_rack_fault), default=None, metavar="SPEC",
                        help=f"simulated pump: its control rack binds or drags, one of {', '.join(RACK_PRESETS)} "
                             f"and/or key=value pairs (keys {', '.join(RACK_KEYS)}), e.g. bind,bind_at_mm=8 "
                             "(default: none); the part diagnosis must name the rack")
    parser.add_argument("--sensor-fault", type=_fault_type(parse_sensor_fault), default=None, metavar="SPEC",
                        help=f"simulated pump: its rack-travel sensor misreads, one of {', '.join(SENSOR_PRESETS)} "
                             f"and/or key=value pairs (keys {', '.join(SENSOR_KEYS)}), e.g. gain=1.05 (default: "
                             "none); the part diagnosis must name the sensor")
