"""python-can's bus settings, read as python-can reads them but never failing on what a shop's PC holds.

python-can takes a bus's settings from its environment (``CAN_INTERFACE``,
``CAN_CHANNEL``, ``CAN_BITRATE``, and ``CAN_CONFIG``: a JSON object of
further arguments) and its config files (``can.util.CONFIG_FILES``: on Linux
``~/can.conf``, ``/etc/can.conf``, ``~/.can``, ``~/.canrc``; later files win),
section ``[default]``. It reads those files with :mod:`configparser` in the
locale's encoding, so one Latin-1 comment (``# Prüfstand 2``) made it raise
``UnicodeDecodeError``, and a bad ``CAN_CONFIG`` a ``JSONDecodeError``. Here
each file is read in the encoding it was written in (a byte-order mark's,
else UTF-8, else Windows-1252 / Latin-1), and anything that cannot be read
is refused in one line naming the file or the variable
(:class:`~edc_bench.errors.RigError`: the bus cannot be set up). The bus is
then opened with python-can's ``ignore_config=True``, on these settings.

What each of python-can's interfaces needs besides python-can (a driver, a
package, a channel, further arguments) is known here too, for messages that
say what to install or give (:func:`interface_needs`), and
:func:`python_can_voice` holds back what python-can and its drivers log
while a bus opens, so that a bus that does not open is said in one line.
"""

from __future__ import annotations

import codecs
import configparser
import contextlib
import inspect
import json
import logging
import os
import sys
import warnings
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from edc_bench.canlib import can
from edc_bench.errors import RigError

#: The section of a config file python-can reads when no context is given.
SECTION = "default"

#: python-can's environment variables for the settings with a name of their own.
ENVIRONMENT = {"interface": "CAN_INTERFACE", "channel": "CAN_CHANNEL", "bitrate": "CAN_BITRATE"}

#: The environment variable holding a JSON object of further arguments.
CAN_CONFIG = "CAN_CONFIG"


class BusSettings(dict[str, Any]):
    """The settings of a python-can bus, knowing where those no flag gave came from.

    A plain dict for every caller (python-can's keyword arguments); :attr:`origin`
    only makes the messages about the bus name the file or variable that chose it.

    Attributes
    ----------
    origin : str
        Where the settings no flag gave came from, e.g. ``"interface from /home/bench/.canrc"``; empty if
        the flags gave them all.
    """

    def __init__(self, values: Mapping[str, Any], origin: str = "") -> None:
        super().__init__(values)
        self.origin = origin


# -- what each interface needs ---------------------------------------------------------------------------------------


@dataclass(frozen=True)
class InterfaceNeeds:
    """What one of python-can's interfaces needs besides python-can.

    Attributes
    ----------
    install : str
        The driver, library or package to install or have ("" if python-can alone does).
    channel : str
        What ``--channel`` is for this interface, with an example.
    channel_required : bool
        Whether the interface cannot do without a channel even where python-can's signature has a default.
    """

    install: str
    channel: str
    channel_required: bool = False


_SERIAL_PORT = "the adapter's serial port, e.g. --channel /dev/ttyUSB0 (Windows: COM3)"

#: What python-can's interfaces need, by name. An interface not listed (a newer python-can's, a plugin's) is
#: pointed at python-can's documentation; its required arguments are still read off its bus class.
NEEDS: dict[str, InterfaceNeeds] = {
    "canalystii": InterfaceNeeds("the canalystii package (pip install 'python-can[canalystii]') and libusb",
                                 "the channel number, e.g. --channel 0"),
    "cantact": InterfaceNeeds("the cantact package (pip install 'python-can[cantact]')",
                              "the channel number, e.g. --channel 0"),
    "etas": InterfaceNeeds("ETAS's BOA driver (Windows only)",
                           "the BOA URI of the channel, e.g. --channel ETAS://ETH/ES910:abcd/CAN:1"),
    "gs_usb": InterfaceNeeds("the gs_usb package (pip install 'python-can[gs-usb]') and libusb",
                             "the device's USB name, e.g. --channel canable --bus-option index=0"),
    "iscan": InterfaceNeeds("Thorsis's isCAN driver library (iscandrv)", "the device number, e.g. --channel 0"),
    "ixxat": InterfaceNeeds("HMS's IXXAT VCI driver (Windows)", "the channel number, e.g. --channel 0"),
    "kvaser": InterfaceNeeds("Kvaser's CANlib driver (Linux: linuxcan from kvaser.com; Windows: Kvaser's drivers)",
                             "the channel number, e.g. --channel 0"),
    "neousys": InterfaceNeeds("Neousys's WDT_DIO driver (Windows only)", "the channel number, e.g. --channel 0"),
    "neovi": InterfaceNeeds("the python-ics package (pip install 'python-can[neovi]') and Intrepid's libicsneo",
                            "the network, e.g. --channel 1"),
    "nican": InterfaceNeeds("National Instruments' NI-CAN driver (Windows, 32-bit Python only)",
                            "the interface's name, e.g. --channel CAN0"),
    "nixnet": InterfaceNeeds("National Instruments' NI-XNET driver (Windows only) and the nixnet package "
                             "(pip install 'python-can[nixnet]')", "the interface's name, e.g. --channel CAN1"),
    "pcan": InterfaceNeeds("PEAK's PCAN-Basic library (Linux: libpcanbasic from peak-system.com; Windows: PEAK's "
                           "driver)", "the PCAN channel, e.g. --channel PCAN_USBBUS1"),
    "robotell": InterfaceNeeds("pyserial (pip install pyserial)", _SERIAL_PORT, channel_required=True),
    "seeedstudio": InterfaceNeeds("pyserial (pip install 'python-can[seeedstudio]')", _SERIAL_PORT,
                                  channel_required=True),
    "serial": InterfaceNeeds("pyserial (pip install 'python-can[serial]')", _SERIAL_PORT, channel_required=True),
    "slcan": InterfaceNeeds("pyserial (pip install 'python-can[serial]')",
                            "the adapter's serial port or a TCP address, e.g. --channel /dev/ttyACM0 or --channel "
                            "socket://127.0.0.1:5000", channel_required=True),
    "socketcan": InterfaceNeeds("Linux's SocketCAN (the can and can_raw kernel modules; in a container, the host's "
                                "CAN network shared with it)",
                                "the CAN network interface, up, e.g. --channel can0 (ip link set can0 up type can "
                                "bitrate 500000)", channel_required=True),
    "socketcand": InterfaceNeeds("a socketcand server it can reach (socketcand -i can0 on the PC with the adapter; "
                                 "its default port is 29536)",
                                 "the CAN interface on the socketcand host, e.g. --channel can0",
                                 channel_required=True),
    "systec": InterfaceNeeds("SYS TEC's USB-CANmodul driver (Windows only)", "the channel number, e.g. --channel 0"),
    "udp_multicast": InterfaceNeeds("msgpack (pip install 'python-can[multicast]')",
                                    "a multicast address, e.g. --channel 239.74.163.2"),
    "usb2can": InterfaceNeeds("8devices' USB2CAN driver and pywin32 (Windows only)",
                              "the adapter's serial number, e.g. --channel ED000100"),
    "vector": InterfaceNeeds("Vector's XL Driver Library (Windows only)", "the channel index, e.g. --channel 0"),
    "virtual": InterfaceNeeds("", "any name (buses on the same channel in one process talk), e.g. --channel bench"),
}

#: python-can's page of every interface, for one edc-bench knows nothing about.
INTERFACES_PAGE = "https://python-can.readthedocs.io/en/stable/interfaces.html"

#: Examples of the further arguments an interface may require, for the message that asks for them.
_ARGUMENT_EXAMPLES = {"host": "192.168.1.10", "port": "29536"}


def rig_on_this_pc(bus_config: BusSettings) -> bool:
    """Whether the bus reaches a rig that is a process on this PC: slcan over a loopback socket (``edc-bench rig
    --listen 127.0.0.1:PORT``) or a pseudo-terminal (``rig --pty``). A USB adapter or a socketcan interface is a
    cable away."""
    import ipaddress
    from urllib.parse import urlsplit

    channel = str(bus_config.get("channel") or "")
    if bus_config.get("interface") != "slcan":
        return False
    if channel.startswith("/dev/pts/"):
        return True
    if not channel.startswith("socket://"):
        return False
    host = urlsplit(channel).hostname or ""
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def interface_needs(interface: str, channel: bool = True) -> str:
    """What ``interface`` needs, in words for the end of a message: what to install and (``channel``) what
    ``--channel`` is for it; "" for an interface that needs nothing to be said."""
    needs = NEEDS.get(interface)
    if needs is None:
        return f"see python-can's page of the {interface} interface ({INTERFACES_PAGE}) for what it needs"
    words = ([f"{interface} needs {needs.install}"] if needs.install else []) + (
        [f"its --channel is {needs.channel}" if needs.install else f"{interface}'s --channel is {needs.channel}"]
        if channel else [])
    return "; ".join(words)


#: What python-can and its drivers said while an interface's module was imported (once a process): a driver
#: missing often shows only there ("Kvaser canlib is unavailable."), and the bus fails later without a word of it.
_SAID_ON_IMPORT: dict[str, PythonCanVoice] = {}


def said_on_import(interface: str) -> list[str]:
    """What python-can said while importing ``interface``'s module, one line each (:func:`bus_class`)."""
    voice = _SAID_ON_IMPORT.get(interface)
    return voice.lines() if voice is not None else []


def replay_said_on_import(interface: str) -> None:
    """Let out what importing ``interface`` said, once: its bus opened, so those warnings are python-can's to give."""
    voice = _SAID_ON_IMPORT.pop(interface, None)
    if voice is not None:
        voice.replay()
        _SAID_ON_IMPORT[interface] = PythonCanVoice()  # said once; later messages have nothing to add


def bus_class(interface: str) -> type:
    """The bus class of ``interface``, imported as python-can imports it (a driver missing shows here or on opening).

    What the import logs or warns is held back (:func:`said_on_import`), for the one line that says why a bus
    does not open.

    Raises
    ------
    Exception
        Whatever importing the interface's module raises (ImportError, OSError, AttributeError of a Windows-only
        module...): the caller turns it into one line.
    """
    import importlib

    module_name, class_name = can.interfaces.BACKENDS[interface]  # python-can's table, plugins' entry points too
    with python_can_voice() as voice:
        try:
            return getattr(importlib.import_module(module_name), class_name)
        finally:
            if interface not in _SAID_ON_IMPORT:
                _SAID_ON_IMPORT[interface] = voice


def missing_arguments(interface: str, cls: type, settings: Mapping[str, Any]) -> list[str]:
    """The arguments ``interface`` requires that ``settings`` lacks (read off its bus class), channel first."""
    try:
        parameters = list(inspect.signature(cls.__init__).parameters.values())[1:]
    except (TypeError, ValueError):  # a class whose signature cannot be read: python-can will say
        parameters = []
    required = [p.name for p in parameters if p.default is inspect.Parameter.empty
                and p.kind in (inspect.Parameter.POSITIONAL_OR_KEYWORD, inspect.Parameter.KEYWORD_ONLY)]
    needs = NEEDS.get(interface)
    if needs is not None and needs.channel_required and "channel" not in required:
        required.insert(0, "channel")
    return [name for name in required if settings.get(name) in (None, "")]


def missing_arguments_message(interface: str, missing: list[str]) -> str:
    """What to give for the ``missing`` arguments of ``interface``, in one sentence."""
    needs = NEEDS.get(interface)
    flags = [f"--bus-option {name}={_ARGUMENT_EXAMPLES.get(name, name.upper())}" for name in missing
             if name != "channel"]
    where = ["CAN_CONFIG"] if flags else []
    if "channel" in missing:
        flags.insert(0, f"--channel ({needs.channel})" if needs else "--channel")
        where.insert(0, "CAN_CHANNEL")
    return (f"the {interface} interface needs {' and '.join(flags)}; {' or '.join(where)} or python-can's config file "
            "can give them too")


# -- python-can's own sources, read robustly ------------------------------------------------------------------------


def config_files() -> list[Path]:
    """The config files python-can reads on this platform, in its order (a later file wins)."""
    return [Path(os.path.expanduser(name)) for name in can.util.CONFIG_FILES]


def read_config_file(path: Path, section: str = SECTION) -> dict[str, str]:
    """The ``[section]`` of one of python-can's config files, in the encoding it was written in; {} if absent.

    Raises
    ------
    RigError
        The file cannot be read, is not text, or is not a config file python-can could read: naming the file
        and what to do.
    """
    try:
        data = path.read_bytes()
    except FileNotFoundError:
        return {}
    except IsADirectoryError:
        raise RigError(f"{path}: is a folder, not python-can's config file; move it aside") from None
    except OSError as exc:
        raise RigError(f"{path}: python-can's config file cannot be read ({exc.strerror or exc}); make it readable "
                       "or move it aside") from None
    text = _decode(path, data)
    parser = configparser.ConfigParser()
    parser.optionxform = str  # type: ignore[assignment, method-assign]  # keys keep their case, as python-can's
    try:
        parser.read_string(text, source=str(path))
        return dict(parser.items(section)) if parser.has_section(section) else {}
    except configparser.Error as exc:
        raise RigError(f"{path}: not a config file python-can can read: {_config_problem(exc)}; fix it (python-can "
                       f"wants [{section}] then KEY = VALUE lines) or move it aside") from None


def _decode(path: Path, data: bytes) -> str:
    """``data`` as text: by its byte-order mark, else UTF-8, else Windows-1252, else Latin-1 (every byte is text)."""
    # UTF-32's little-endian mark starts with UTF-16's: looked for first
    for bom, codec, name in ((codecs.BOM_UTF8, "utf-8-sig", "UTF-8"), (codecs.BOM_UTF32_LE, "utf-32", "UTF-32"),
                             (codecs.BOM_UTF32_BE, "utf-32", "UTF-32"), (codecs.BOM_UTF16_LE, "utf-16", "UTF-16"),
                             (codecs.BOM_UTF16_BE, "utf-16", "UTF-16")):
        if data.startswith(bom):
            try:
                return data.decode(codec)
            except UnicodeDecodeError as exc:
                raise RigError(f"{path}: starts with a {name} byte-order mark but is not {name} text (byte "
                               f"{exc.start}); save it again as UTF-8") from None
    if b"\x00" in data:
        raise RigError(f"{path}: not a text file (it holds NUL bytes: binary, or UTF-16 without a byte-order mark); "
                       "python-can's config file is text: save it as UTF-8 or move it aside")
    for codec in ("utf-8", "cp1252"):
        try:
            return data.decode(codec)
        except UnicodeDecodeError:
            pass
    return data.decode("latin-1")


def _config_problem(exc: configparser.Error) -> str:
    """configparser's several-line message in a few words, naming the line."""
    if isinstance(exc, configparser.MissingSectionHeaderError):
        return f"line {exc.lineno}, {_quoted(exc.line)}, comes before any [section] line"
    if isinstance(exc, configparser.DuplicateSectionError):
        return f"section [{exc.section}] twice (line {exc.lineno})"
    if isinstance(exc, configparser.DuplicateOptionError):
        return f"{exc.option} twice in [{exc.section}] (line {exc.lineno})"
    if isinstance(exc, configparser.ParsingError):
        lineno, line = exc.errors[0]  # as repr() shows it up to Python 3.12, the line itself from 3.13 on
        shown = line if len(line) >= 2 and line[0] in "'\"" and line[-1] == line[0] else repr(line.rstrip("\r\n"))
        return f"line {lineno}, {shown if len(shown) <= 42 else shown[:38] + '...'}, is not KEY = VALUE"
    if isinstance(exc, configparser.InterpolationError):
        return f"[{exc.section}] {exc.option}: a % must be written %% (python-can reads %(name)s as another key)"
    return str(exc).splitlines()[0]


def _quoted(line: str) -> str:
    line = line.strip()
    return repr(line if len(line) <= 40 else line[:37] + "...")


def file_config(section: str = SECTION) -> tuple[dict[str, str], dict[str, Path]]:
    """python-can's config files merged as python-can merges them (a later file wins): the values, and each one's file.

    Raises
    ------
    RigError
        A file that cannot be read, naming it (:func:`read_config_file`).
    """
    values: dict[str, str] = {}
    sources: dict[str, Path] = {}
    for path in config_files():
        for key, value in read_config_file(path, section).items():
            values[key], sources[key] = value, path
    return values, sources


def environment_config(environ: Mapping[str, str] | None = None) -> tuple[dict[str, Any], dict[str, str]]:
    """python-can's environment settings (``CAN_CONFIG`` then ``CAN_INTERFACE``...): the values, and each one's
    variable.

    Raises
    ------
    RigError
        ``CAN_CONFIG`` that is not a JSON object.
    """
    environ = os.environ if environ is None else environ
    values: dict[str, Any] = {}
    sources: dict[str, str] = {}
    raw = environ.get(CAN_CONFIG, "")
    if raw.strip():
        try:
            loaded = json.loads(raw)
        except ValueError as exc:
            raise RigError(f"{CAN_CONFIG}: not JSON ({exc}); give a JSON object of python-can bus arguments, e.g. "
                           f"{CAN_CONFIG}='{{\"host\": \"192.168.1.10\", \"port\": 29536}}', or unset it") from None
        if not isinstance(loaded, dict):
            raise RigError(f"{CAN_CONFIG}: a JSON {type(loaded).__name__}, not an object; give python-can bus "
                           f"arguments as {{\"KEY\": VALUE, ...}}, or unset it")
        values.update(loaded)
        sources.update(dict.fromkeys(loaded, CAN_CONFIG))
    for key, variable in ENVIRONMENT.items():
        if environ.get(variable):
            values[key], sources[key] = environ[variable], variable
    return values, sources


def python_can_config() -> tuple[dict[str, Any], dict[str, str]]:
    """The bus settings python-can's own sources give: ``can.rc``, then the environment, then the config files
    (the first that gives a key wins, as in python-can). The values, and where each came from.

    The legacy key ``bustype`` names the interface when nothing else does, as python-can reads it.

    Raises
    ------
    RigError
        A config file or ``CAN_CONFIG`` that cannot be read, naming it.
    """
    env, env_sources = environment_config()
    files, file_sources = file_config()
    values: dict[str, Any] = {}
    sources: dict[str, str] = {}
    for layer, where in ((dict(getattr(can, "rc", {}) or {}), {}), (env, env_sources), (files, file_sources)):
        layer = dict(layer)
        if "bustype" in layer:
            if not layer.get("interface"):
                layer["interface"] = layer["bustype"]
                where = {**where, "interface": where.get("bustype", "can.rc")}
            del layer["bustype"]
        for key, value in layer.items():
            if key not in values:
                values[key], sources[key] = value, str(where.get(key, "can.rc"))
    return values, sources


def bus_keyword_arguments(settings: Mapping[str, Any]) -> dict[str, Any]:
    """``settings`` as python-can would hand them to the bus class: text values cast as python-can casts its
    config file's (``"0"`` is 0, ``"true"`` is True), and checked by python-can's own rules (``port`` a number, ...).

    Raises
    ------
    ValueError, TypeError
        A value python-can refuses (the caller says it in one line).
    """
    out = {key: can.util.cast_from_string(value) if isinstance(value, str) and key != "interface" else value
           for key, value in settings.items()}
    create = getattr(can.util, "_create_bus_config", None)  # python-can's checks of a config (port, state, timing)
    return dict(create(out)) if create is not None else out


# -- what python-can says while a bus opens ----------------------------------------------------------------------------


class _Held(logging.Handler):
    """Keeps log records (a few distinct ones) instead of printing them."""

    LIMIT = 20

    def __init__(self, records: list[logging.LogRecord]) -> None:
        super().__init__(logging.DEBUG)
        self.records = records

    def emit(self, record: logging.LogRecord) -> None:
        if len(self.records) < self.LIMIT:  # a driver retrying a connection logs thousands
            self.records.append(record)


class PythonCanVoice:
    """What python-can and its drivers said (logged, warned, raised in a destructor) while a bus was set up.

    Attributes
    ----------
    records : list of logging.LogRecord
        The log records held back.
    """

    def __init__(self) -> None:
        self.records: list[logging.LogRecord] = []
        self.warned: list[warnings.WarningMessage] = []
        self.unraisable: list[str] = []

    def lines(self) -> list[str]:
        """What was said, one distinct line each, without the noise of a bus that never opened."""
        said = [record.getMessage() for record in self.records if record.levelno >= logging.WARNING]
        said += [str(w.message) for w in self.warned] + self.unraisable
        out: list[str] = []
        for line in said:
            line = " ".join(line.split())
            if line and line not in out and "was not properly shut down" not in line:
                out.append(line)
        return out

    def replay(self) -> None:
        """Say it after all, as it would have been said (the bus opened: its warnings are not ours to hide)."""
        for record in self.records:
            logging.getLogger(record.name).handle(record)
        for w in self.warned:
            warnings.showwarning(w.message, w.category, w.filename, w.lineno)


@contextlib.contextmanager
def python_can_voice() -> Iterator[PythonCanVoice]:
    """Hold back what python-can and its drivers print while a bus is set up (a driver missing logs a warning on
    import, a failed bus one in its destructor), for the one line that says why the bus did not open.

    Every logger's records that reach the root logger are held (python-can's, and a plugin interface's own), as
    are warnings and errors raised in destructors; the caller says them (:meth:`PythonCanVoice.lines`) or lets
    them out (:meth:`PythonCanVoice.replay`).
    """
    voice = PythonCanVoice()
    root = logging.getLogger()
    # the held handler alone, meanwhile: logging's last resort (stderr) and any configured handler stay silent (a
    # record would show twice, now and when let out), as does an outer hold (an import inside an opening)
    handlers, root.handlers = root.handlers, [_Held(voice.records)]
    can_logger = logging.getLogger("can")
    propagate, can_logger.propagate = can_logger.propagate, True
    hook = sys.unraisablehook
    sys.unraisablehook = lambda u: voice.unraisable.append(f"{getattr(u.exc_type, '__name__', '')}: {u.exc_value}")
    try:
        with warnings.catch_warnings(record=True) as caught:
            try:
                yield voice
            finally:
                voice.warned.extend(caught)
    finally:
        sys.unraisablehook = hook
        can_logger.propagate = propagate
        root.handlers = handlers


def one_line(text: str, limit: int = 300) -> str:
    """``text`` on one line, cut at ``limit`` characters."""
    text = " ".join(str(text).split())
    return text if len(text) <= limit else text[:limit - 3] + "..."


def exception_words(exc: BaseException) -> str:
    """What an exception from python-can or a driver says, on one line (its type where its text alone is unclear)."""
    text = one_line(str(exc))
    if isinstance(exc, can.CanError) and text:
        return text
    return f"{type(exc).__name__}: {text}" if text else type(exc).__name__


# -- one line for a bus that cannot be set up ------------------------------------------------------------------------


def bus_problem(settings: Mapping[str, Any], why: str, said: list[str] | None = None, channel: bool = True,
                install: bool = True) -> str:
    """The line that says a bus does not open: its settings (and where they came from), why, what python-can
    said, and what the interface needs.

    Parameters
    ----------
    settings
        The bus's settings as given (a :class:`BusSettings` names where they came from).
    why
        Why it does not open, in a few words.
    said
        What python-can and its drivers said meanwhile (:meth:`PythonCanVoice.lines`).
    channel, install
        Whether to end by saying what ``--channel`` is for the interface (not when ``why`` says it already), and
        what it needs installed.
    """
    interface = str(settings.get("interface"))
    where = ", ".join(f"{key}={value}" for key, value in settings.items())
    origin = getattr(settings, "origin", "")
    lines = [line for line in [*said_on_import(interface), *(said or [])] if line not in why]
    extra = f" (python-can: {one_line('; '.join(dict.fromkeys(lines)), 200)})" if lines else ""
    needs = interface_needs(interface, channel) if install else ""
    return f"cannot open the CAN bus ({where}{'; ' + origin if origin else ''}): {why}{extra}{'; ' + needs if needs else ''}"


def check_interface(settings: Mapping[str, Any]) -> None:
    """Refuse, before any work, a bus whose interface cannot load here or lacks an argument it requires.

    Loads the interface's module (a driver or package missing often shows here) and reads the arguments its bus
    class requires (socketcand's ``host`` and ``port``, most interfaces' channel). Whether the adapter is there
    shows only when the bus opens (:func:`edc_bench.runtime.bus.open_bus`).

    Raises
    ------
    RigError
        In one line naming the interface, what is missing and what to install or give.
    """
    interface = str(settings["interface"])
    try:
        cls = bus_class(interface)
    except Exception as exc:  # noqa: BLE001 - whatever a driver's module raises on import, it cannot load
        raise RigError(bus_problem(settings, f"python-can cannot load its {interface} interface here: "
                                             f"{exception_words(exc)}")) from None
    missing = missing_arguments(interface, cls, settings)
    if missing:
        raise RigError(missing_arguments_problem(settings, interface, missing))


def missing_arguments_problem(settings: Mapping[str, Any], interface: str, missing: list[str]) -> str:
    """The line for a bus that lacks arguments its interface requires: what to give, and what to install only if
    the interface needs more than a channel or its import said something is missing."""
    install = missing != ["channel"] or bool(said_on_import(interface))
    return bus_problem(settings, missing_arguments_message(interface, missing), channel=False, install=install)
