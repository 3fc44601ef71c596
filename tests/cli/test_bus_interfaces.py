"""Every interface python-can names, through ``test``, ``rig-check`` and ``calibrate``: it opens, or it is refused
in one line with exit 3 that names it and says what to install or give; never a traceback.

The interfaces are python-can's own list (``can.interfaces.VALID_INTERFACES``), read when the tests are collected,
so a newer python-can's interface, or a plugin's, is in the table the day it is installed. Each is given the
three ways python-can takes a bus: by flag, by its environment variables, and in its config file (``~/.canrc``,
under a HOME of the test's own); and by flag without a channel. The commands run in process (a subprocess costs
a second); what a command does once its bus is open (a test, a rig check, a calibration, each waiting for a rig
that is not there) is replaced by a stand-in that notes the bus and stops: an interface that opens here
(``virtual``, and whatever adapter this machine has) proceeds to the work with its bus open, and the bus is shut
afterwards (the slow pass runs the real work on them: no rig answers, and each command says so in its way). One
subprocess runs every interface in a fresh interpreter, where each driver's module is imported for the first time
and logs its warnings (a Kvaser driver missing shows only there); an interface registered as a plugin stands for
one edc-bench knows nothing about.

Then the measured failures of issue 52, one test each: a Kvaser interface without its driver, socketcand (it
needs a host and a port, given by ``--bus-option``), ``serial`` or ``robotell`` with ``--channel 0``, and a
``~/.canrc`` with a Latin-1 comment; and the config-file table: the file in each encoding it may have been
written in is read, a file that cannot be read is refused naming it.
"""

from __future__ import annotations

import json
import os
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import can
import pytest
from helpers import REPO, run_cli

from edc_bench.cli.exit_codes import ExitCode
from edc_bench.errors import RigError

INTERFACES = sorted(can.interfaces.VALID_INTERFACES)
COMMANDS = ("test", "rig-check", "calibrate")
#: the ways python-can takes a bus
GIVEN = ("flag", "flag-no-channel", "environment", "canrc")
#: what each command needs so that it runs without the station (no history) and writes into the test's folder
BASE = {"test": ["test", "--no-history", "--out", "rec"], "rig-check": ["rig-check", "--out", "rc"],
        "calibrate": ["calibrate", "--out", "rec"]}
#: the stand-in's line: the command reached its work with the bus open
OPENED = "stand-in for the work: the bus opened"
#: interfaces python-can opens without hardware (no rig answers on them, which is not the table's business)
SOFTWARE = {"virtual"}


class WorkReached:
    """What the stand-ins saw: the buses the commands' work got, and whether the simulated rig was used instead."""

    def __init__(self) -> None:
        self.buses: list[can.BusABC] = []
        self.simulated: list[str] = []


@pytest.fixture()
def bench(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[WorkReached]:
    """A fresh HOME (no ~/.canrc), python-can's environment unset, a working folder, the work replaced."""
    home = tmp_path / "home"
    home.mkdir()
    for name, value in (("HOME", home), ("XDG_CONFIG_HOME", home / ".config"), ("APPDATA", home / "AppData"),
                        ("EDC_BENCH_DATA_DIR", tmp_path / "data"), ("EDC_BENCH_CACHE_DIR", tmp_path / "cache")):
        monkeypatch.setenv(name, str(value))
    for name in ("CAN_INTERFACE", "CAN_CHANNEL", "CAN_BITRATE", "CAN_CONFIG", "EDC_BENCH_HISTORY_URL"):
        monkeypatch.delenv(name, raising=False)
    # python-can's files in the user's folder only: a machine's own /etc/can.conf stays out of the table
    monkeypatch.setattr(can.util, "CONFIG_FILES", [f for f in can.util.CONFIG_FILES if f.startswith("~")])
    work = tmp_path / "work"
    work.mkdir()
    monkeypatch.chdir(work)
    reached = WorkReached()

    def on_a_bus(bus: can.BusABC, *args: object, **kwargs: object) -> None:
        reached.buses.append(bus)
        raise RigError(OPENED)

    def simulated(*args: object, **kwargs: object) -> None:
        reached.simulated.append("simulated")
        raise RigError(OPENED.replace("the bus opened", "the simulated rig"))

    monkeypatch.setattr("edc_bench.bench.run_bench_test", on_a_bus)
    monkeypatch.setattr("edc_bench.rigcheck.run_rig_check", on_a_bus)
    monkeypatch.setattr("edc_bench.bench.run_simulated_test", simulated)
    monkeypatch.setattr("edc_bench.population.calibrate.population_tests", simulated)
    yield reached


def lines(text: str) -> list[str]:
    return [line for line in text.splitlines() if line.strip()]


def write_canrc(text: str | bytes) -> Path:
    path = Path(os.path.expanduser("~/.canrc"))
    if isinstance(text, bytes):
        path.write_bytes(text)
    else:
        path.write_text(text, encoding="utf-8")
    return path


def argv_for(command: str, interface: str, given: str, monkeypatch: pytest.MonkeyPatch) -> list[str]:
    """The command line (and environment, config file) that gives ``interface`` the way ``given`` says."""
    argv = list(BASE[command])
    # rig-check and calibrate take a bus from their flags; python-can's sources only complete them
    completing = [] if command == "test" else ["--bitrate", "500000"]
    if given == "flag":
        return argv + ["--interface", interface, "--channel", "0"]
    if given == "flag-no-channel":
        return argv + ["--interface", interface]
    if given == "environment":
        monkeypatch.setenv("CAN_INTERFACE", interface)
        monkeypatch.setenv("CAN_CHANNEL", "0")
        return argv + completing
    write_canrc(f"# the bench's adapter\n[default]\ninterface = {interface}\nchannel = 0\n")
    return argv + completing


def assert_opened_or_refused(interface: str, code: int, out: str, err: str, reached: WorkReached) -> None:
    """The table's rule: the bus opened and the work got it (shut afterwards), or one line, exit 3, naming it."""
    said = out + err
    assert "Traceback" not in said and code != ExitCode.INTERNAL_ERROR, said
    assert not reached.simulated, f"{interface} given, but the simulated rig ran: {said}"
    if reached.buses:  # it opened: the work got an open bus of that interface, and it was shut after the work
        assert code == ExitCode.RIG_ERROR and OPENED in err, said
        assert all(bus._is_shutdown for bus in reached.buses), "the bus was left open"
        return
    assert interface not in SOFTWARE, f"{interface} needs no hardware, but did not open: {said}"
    assert code == ExitCode.RIG_ERROR, f"exit {code}, expected 3: {said}"
    assert out == "", out
    assert len(lines(err)) == 1, f"one line, not {len(lines(err))}: {err}"
    assert interface in err, err
    assert err.startswith("edc-bench ") and ": error: " in err, err


@pytest.mark.parametrize("given", GIVEN)
@pytest.mark.parametrize("command", COMMANDS)
@pytest.mark.parametrize("interface", INTERFACES)
def test_every_python_can_interface_opens_or_is_refused_in_one_line(
        interface: str, command: str, given: str, bench: WorkReached, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = run_cli(argv_for(command, interface, given, monkeypatch), capsys)
    assert_opened_or_refused(interface, code, out, err, bench)
    if given == "canrc" and not bench.buses:
        assert ".canrc" in err  # where the interface came from
    if given == "environment" and not bench.buses:
        assert "CAN_INTERFACE" in err


def test_the_table_holds_every_interface_python_can_lists() -> None:
    assert set(INTERFACES) == set(can.interfaces.BACKENDS) and len(INTERFACES) >= 20
    assert {"kvaser", "socketcand", "serial", "robotell", "virtual", "slcan", "socketcan"} <= set(INTERFACES)


def test_every_interface_in_a_fresh_interpreter_says_one_line(tmp_path: Path) -> None:
    """Each driver's module imported for the first time: what it logs then (a driver missing) is not a second
    line. The work is replaced as in the table; an interface that opens reaches it."""
    script = f"""
import io, json, sys
from edc_bench.errors import RigError
import edc_bench.bench, edc_bench.rigcheck
def reached(*a, **k):
    raise RigError({OPENED!r})
edc_bench.bench.run_bench_test = edc_bench.rigcheck.run_rig_check = reached
from edc_bench.canlib import can
can.util.CONFIG_FILES = [f for f in can.util.CONFIG_FILES if f.startswith("~")]  # not this machine's /etc/can.conf
from edc_bench.cli import main
results = {{}}
for interface in {INTERFACES!r}:
    err = io.StringIO()
    sys.stderr, real = err, sys.stderr
    try:
        code = main(["test", "--no-history", "--out", "rec", "--interface", interface, "--channel", "0"])
    finally:
        sys.stderr = real
    results[interface] = [code, err.getvalue()]
print(json.dumps(results))
"""
    env = {**os.environ, "HOME": str(tmp_path), "EDC_BENCH_DATA_DIR": str(tmp_path / "data")}
    for name in ("CAN_INTERFACE", "CAN_CHANNEL", "CAN_BITRATE", "CAN_CONFIG"):
        env.pop(name, None)
    proc = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, cwd=tmp_path, env=env,
                          timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr == "", proc.stderr  # nothing escaped to the real stderr either
    results = json.loads(proc.stdout)
    assert set(results) == set(INTERFACES)
    for interface, (code, err) in results.items():
        assert code == ExitCode.RIG_ERROR and "Traceback" not in err, (interface, err)
        if OPENED not in err:  # refused; one that opened reached the work, which says what it says
            assert len(lines(err)) == 1 and interface in err, (interface, err)


@pytest.mark.slow  # 7 s: a test and a rig check in real time, each waiting for a rig that is not there
@pytest.mark.parametrize(("command", "code"), [("test", ExitCode.INVALID), ("rig-check", ExitCode.RIG_NOT_CONFORMING),
                                               ("calibrate", ExitCode.INVALID)])
def test_an_interface_that_opens_with_no_rig_on_it_ends_cleanly(command: str, code: int, tmp_path: Path,
                                                                monkeypatch: pytest.MonkeyPatch,
                                                                capsys: pytest.CaptureFixture[str]) -> None:
    """The work itself, not a stand-in, on each interface that opens here without hardware: no rig answers, and
    the command says so in its own way (a test INVALID with its record, a rig check NO-GO) within seconds."""
    monkeypatch.setenv("HOME", str(tmp_path))
    monkeypatch.setenv("EDC_BENCH_DATA_DIR", str(tmp_path / "data"))
    for name in ("CAN_INTERFACE", "CAN_CHANNEL", "CAN_BITRATE", "CAN_CONFIG"):
        monkeypatch.delenv(name, raising=False)
    monkeypatch.chdir(tmp_path)
    source = (REPO / "configs" / "p-edc-default.toml").read_text(encoding="utf-8")
    # no rig will answer: give up waiting for READY after 0.2 s instead of 3
    Path("quick.toml").write_text(source.replace('name = "p-edc-default"', 'name = "quick"')
                                  + "\n[acceptance]\nready_timeout_s = 0.2\n", encoding="utf-8")
    extra = {"test": ["--no-history", "--no-figure", "--valve-id", "V-1"], "rig-check": ["--commands", "100"],
             "calibrate": []}[command]
    for interface in sorted(SOFTWARE & set(INTERFACES)):
        started = time.monotonic()
        got, out, err = run_cli([command, "--variant", "quick.toml", "--interface", interface, "--channel",
                                 "edc-bench-nobody", "--out", "out", *extra], capsys)
        assert got == code and "Traceback" not in out + err, (interface, out, err)
        assert time.monotonic() - started < 30, interface


PLUGIN = """
import logging
import can

logging.getLogger("can.{name}").warning("{name}: its optional speed-up is not installed")


class PluginBus(can.BusABC):
    def __init__(self, channel, station, **kwargs):
        if station == "broken":
            logging.getLogger("can.{name}").warning("{name}: the adapter did not answer")
            raise RuntimeError("no adapter")
        super().__init__(channel=channel, **kwargs)
        self.channel_info = "{name}"

    def send(self, msg, timeout=None):
        pass

    def _recv_internal(self, timeout):
        return None, False
"""


@pytest.fixture()
def plugin(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, request: pytest.FixtureRequest) -> str:
    """An interface edc-bench knows nothing about (a plugin's, a newer python-can's), registered with python-can:
    it requires a ``station`` argument and logs on import and on a failed open. A fresh name each test: its
    module is imported for the first time."""
    name = "plugin_" + "".join(c for c in request.node.name if c.isalnum())
    (tmp_path / f"{name}.py").write_text(PLUGIN.format(name=name), encoding="utf-8")
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setitem(can.interfaces.BACKENDS, name, (name, "PluginBus"))
    valid = frozenset({*can.interfaces.VALID_INTERFACES, name})
    monkeypatch.setattr(can.interfaces, "VALID_INTERFACES", valid)
    monkeypatch.setattr(can.util, "VALID_INTERFACES", valid)  # python-can's config check holds its own name for it
    return name


def test_an_interface_edc_bench_does_not_know_is_asked_for_what_its_bus_requires(
        plugin: str, bench: WorkReached, capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = run_cli(["test", "--no-history", "--interface", plugin, "--channel", "0"], capsys)
    assert code == ExitCode.RIG_ERROR and len(lines(err)) == 1, err
    assert "--bus-option station=STATION" in err and "python-can.readthedocs.io" in err, err


def test_what_a_driver_says_while_its_bus_fails_is_in_the_one_line(plugin: str, bench: WorkReached,
                                                                   capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = run_cli(["rig-check", "--out", "rc", "--interface", plugin, "--channel", "0",
                              "--bus-option", "station=broken"], capsys)
    assert code == ExitCode.RIG_ERROR and len(lines(err)) == 1, err
    assert "RuntimeError: no adapter" in err and "the adapter did not answer" in err, err
    assert "optional speed-up is not installed" in err, err  # said on import, before the bus was asked


def test_what_a_driver_says_while_its_bus_opens_is_let_out_once(plugin: str, bench: WorkReached,
                                                                capsys: pytest.CaptureFixture[str],
                                                                caplog: pytest.LogCaptureFixture) -> None:
    code, out, err = run_cli(["calibrate", "--out", "rec", "--interface", plugin, "--channel", "0",
                              "--bus-option", "station=bench-2"], capsys)
    assert bench.buses and OPENED in err, err
    said = [r.getMessage() for r in caplog.records if r.name == f"can.{plugin}"]
    assert said == [f"{plugin}: its optional speed-up is not installed"], said


# -- the measured failures of issue 52 ------------------------------------------------------------------------------


@pytest.mark.parametrize("given", ("flag", "environment", "canrc"))
def test_kvaser_without_its_driver_says_what_to_install(given: str, bench: WorkReached,
                                                        monkeypatch: pytest.MonkeyPatch,
                                                        capsys: pytest.CaptureFixture[str]) -> None:
    """Was ``NameError: canGetNumberOfChannels``, exit 70, by flag, CAN_INTERFACE and ~/.canrc alike."""
    try:
        from can.interfaces.kvaser import canlib

        if canlib.__dict__.get("canGetNumberOfChannels") is not None:
            pytest.skip("Kvaser's CANlib is installed on this machine")
    except ImportError:
        pass
    code, out, err = run_cli(argv_for("test", "kvaser", given, monkeypatch), capsys)
    assert code == ExitCode.RIG_ERROR and len(lines(err)) == 1 and "Traceback" not in err, err
    assert "kvaser" in err and "CANlib" in err and "linuxcan" in err, err


@pytest.mark.parametrize("interface", ("serial", "robotell"))
def test_a_serial_interface_with_channel_0_asks_for_the_serial_port(interface: str, bench: WorkReached,
                                                                    capsys: pytest.CaptureFixture[str]) -> None:
    """Was ``TypeError: Must specify a serial port.``, exit 70."""
    code, out, err = run_cli(["test", "--no-history", "--interface", interface, "--channel", "0"], capsys)
    assert code == ExitCode.RIG_ERROR and len(lines(err)) == 1 and "Traceback" not in err, err
    assert "serial port" in err and "--channel /dev/ttyUSB0" in err, err


@pytest.mark.parametrize("command", COMMANDS)
def test_socketcand_without_host_and_port_names_the_flags_that_give_them(command: str, bench: WorkReached,
                                                                         capsys: pytest.CaptureFixture[str]) -> None:
    """Was ``TypeError: missing 2 required positional arguments: 'host' and 'port'``, and no way to give them."""
    code, out, err = run_cli([*BASE[command], "--interface", "socketcand", "--channel", "can0"], capsys)
    assert code == ExitCode.RIG_ERROR and len(lines(err)) == 1, err
    assert "--bus-option host=" in err and "--bus-option port=" in err and "29536" in err, err


class FakeSocketcand:
    """A socketcand server of a few lines: greets, opens the channel, goes raw, then keeps the connection."""

    def __init__(self, greet: bool = True) -> None:
        self.server = socket.create_server(("127.0.0.1", 0))
        self.port = self.server.getsockname()[1]
        self.greet = greet
        self.asked: list[str] = []
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._serve, daemon=True)
        self._thread.start()

    def _serve(self) -> None:
        self.server.settimeout(0.1)
        while not self._stop.is_set():
            try:
                conn, _ = self.server.accept()
            except TimeoutError:
                continue
            except OSError:
                return
            threading.Thread(target=self._talk, args=(conn,), daemon=True).start()

    def _talk(self, conn: socket.socket) -> None:
        with conn:
            conn.settimeout(0.1)
            if self.greet:
                conn.sendall(b"< hi >")
            while not self._stop.is_set():
                try:
                    data = conn.recv(256)
                except TimeoutError:
                    continue
                except OSError:
                    return
                if not data:
                    return
                self.asked.append(data.decode("ascii", "replace"))
                if data.startswith((b"< open", b"< rawmode")):
                    conn.sendall(b"< ok >")

    def close(self) -> None:
        self._stop.set()
        self.server.close()
        self._thread.join(2)


@pytest.mark.parametrize("command", COMMANDS)
def test_socketcand_given_host_and_port_by_flag_opens(command: str, bench: WorkReached,
                                                      capsys: pytest.CaptureFixture[str]) -> None:
    server = FakeSocketcand()
    try:
        code, out, err = run_cli([*BASE[command], "--interface", "socketcand", "--channel", "can0",
                                  "--bus-option", "host=127.0.0.1", "--bus-option", f"port={server.port}"], capsys)
    finally:
        server.close()
    assert bench.buses and OPENED in err and "Traceback" not in err, err
    assert any("< open can0 >" in asked for asked in server.asked), server.asked


def test_socketcand_host_and_port_from_can_config_and_canrc(bench: WorkReached, monkeypatch: pytest.MonkeyPatch,
                                                            capsys: pytest.CaptureFixture[str]) -> None:
    """python-can's other sources of further arguments: CAN_CONFIG's JSON object, and the config file's keys."""
    server = FakeSocketcand()
    try:
        monkeypatch.setenv("CAN_CONFIG", json.dumps({"interface": "socketcand", "host": "127.0.0.1",
                                                     "port": server.port}))
        monkeypatch.setenv("CAN_CHANNEL", "can0")
        run_cli(["test", "--no-history", "--out", "rec"], capsys)
        assert len(bench.buses) == 1
        monkeypatch.delenv("CAN_CONFIG")
        monkeypatch.delenv("CAN_CHANNEL")
        write_canrc(f"[default]\ninterface = socketcand\nchannel = can0\nhost = 127.0.0.1\nport = {server.port}\n")
        code, out, err = run_cli(["calibrate", "--out", "rec", "--bitrate", "500000"], capsys)
        assert len(bench.buses) == 2 and OPENED in err, err
    finally:
        server.close()


def test_socketcand_that_is_not_there_is_said_at_once(bench: WorkReached, capsys: pytest.CaptureFixture[str]) -> None:
    """python-can retries a refused connection for 10 s, a log line each time; here: one line, at once."""
    with socket.create_server(("127.0.0.1", 0)) as probe:
        port = probe.getsockname()[1]  # free once closed: nothing listens there
    started = time.monotonic()
    code, out, err = run_cli(["test", "--no-history", "--interface", "socketcand", "--channel", "can0",
                              "--bus-option", "host=127.0.0.1", "--bus-option", f"port={port}"], capsys)
    # a hang guard, not a speed check: python-can alone retries for 10 s, a log line each time, and the refusal
    # here takes milliseconds; 30 s only a hang passes
    assert time.monotonic() - started < 30 and len(lines(err)) == 1, err
    assert code == ExitCode.RIG_ERROR and len(lines(err)) == 1, err
    assert f"nothing listens at 127.0.0.1:{port}" in err and "connection refused" in err, err


def test_a_server_that_accepts_and_never_greets_is_given_up_in_seconds(bench: WorkReached,
                                                                       monkeypatch: pytest.MonkeyPatch,
                                                                       capsys: pytest.CaptureFixture[str]) -> None:
    """python-can would wait for socketcand's greeting without limit: a hung command."""
    monkeypatch.setattr("edc_bench.runtime.bus.SOCKETCAND_TIMEOUT_S", 0.3)
    server = FakeSocketcand(greet=False)
    try:
        started = time.monotonic()
        code, out, err = run_cli(["rig-check", "--out", "rc", "--interface", "socketcand", "--channel", "can0",
                                  "--bus-option", "host=127.0.0.1", "--bus-option", f"port={server.port}"], capsys)
        assert time.monotonic() - started < 30  # a hang guard: python-can alone waits without limit (here: 0.4 s)
    finally:
        server.close()
    assert code == ExitCode.RIG_ERROR and len(lines(err)) == 1, err
    assert "said nothing within 0.3 s" in err, err


@pytest.mark.parametrize(("argv", "words"), [
    (["--bus-option", "host"], ("'host' is not KEY=VALUE", "--bus-option host=")),
    (["--bus-option", "=5"], ("is not KEY=VALUE",)),
    (["--bus-option", "channel=can0"], ("has a flag of its own", "--channel can0")),
    (["--bus-option", "host=a", "--bus-option", "host=b"], ("--bus-option host is given twice",)),
    (["--bus-option", "host=a"], ("--bus-option host is an argument of a bus", "--interface")),
])
def test_a_bus_option_that_cannot_be_right_is_bad_input(argv: list[str], words: tuple[str, ...], bench: WorkReached,
                                                        capsys: pytest.CaptureFixture[str]) -> None:
    if "host=a" in argv and argv.count("--bus-option") == 2:
        argv = [*argv, "--interface", "socketcand", "--channel", "can0"]
    code, out, err = run_cli(["rig-check", "--out", "rc", *argv], capsys)
    assert code == ExitCode.BAD_INPUT and len(lines(err)) == 1, err
    assert all(word in err for word in words), err


# -- python-can's config file, in whatever encoding it was written ----------------------------------------------------

#: a comment a shop writes in its own language, in each encoding an editor may save it in
ENCODED = {
    "utf-8": "# Prüfstand 2 – Ölpumpen\n".encode(),
    "utf-8 with BOM": "\ufeff# Prüfstand 2 – Ölpumpen\n".encode(),
    "latin-1": "# Prüfstand 2 (Ölpumpen)\n".encode("latin-1"),
    "windows-1252": "# Prüfstand 2 – „Ölpumpen“ 5 €\n".encode("cp1252"),
    "utf-16": "# Prüfstand 2 – Ölpumpen\n".encode("utf-16"),
}
#: an interface that is refused the same way on every machine (no socketcand host given), so the table shows the
#: file was read: its interface and channel reach the message
CONFIGURED = "[default]\ninterface = socketcand\nchannel = can0\n"


def encoded(encoding: str, extra: str) -> bytes:
    comment = ENCODED[encoding]
    codec = {"utf-8 with BOM": "utf-8", "windows-1252": "cp1252", "utf-16": "utf-16-le"}.get(encoding, encoding)
    return comment + extra.encode(codec)


@pytest.mark.parametrize("command", COMMANDS)
@pytest.mark.parametrize("encoding", list(ENCODED))
def test_a_config_file_is_read_in_the_encoding_it_was_written_in(encoding: str, command: str, bench: WorkReached,
                                                                 capsys: pytest.CaptureFixture[str]) -> None:
    path = write_canrc(encoded(encoding, CONFIGURED))
    completing = [] if command == "test" else ["--bitrate", "500000"]
    code, out, err = run_cli([*BASE[command], *completing], capsys)
    assert code == ExitCode.RIG_ERROR and len(lines(err)) == 1 and "Traceback" not in err, err
    assert "interface=socketcand, channel=can0" in err and str(path) in err and "--bus-option host=" in err, err


@pytest.mark.parametrize("encoding", list(ENCODED))
def test_the_simulated_demo_runs_beside_a_config_file_in_any_encoding(encoding: str, bench: WorkReached,
                                                                      capsys: pytest.CaptureFixture[str]) -> None:
    """A ``~/.canrc`` with a Latin-1 comment broke every ``edc-bench test``, the demo included (exit 70)."""
    write_canrc(encoded(encoding, "[default]\n"))
    code, out, err = run_cli(["test", "--no-history", "--out", "rec"], capsys)
    assert bench.simulated and not bench.buses and "Traceback" not in err, err


def test_commands_that_need_no_bus_do_not_read_the_config_file(bench: WorkReached,
                                                               capsys: pytest.CaptureFixture[str]) -> None:
    write_canrc(b"\x00\x01 not a config file")
    for command in ("rig-check", "calibrate"):  # the simulated rig (rig-check's in process), never the file
        code, out, err = run_cli(BASE[command], capsys)
        assert "stand-in for the work" in err and ".canrc" not in err, err


#: files python-can cannot read: each refused in one line naming the file and what is wrong with it
DAMAGED = {
    "binary": (b"\x00\x01\x02binary\xff", "not a text file"),
    "utf-16 without a mark": ("[default]\ninterface = virtual\n".encode("utf-16-le"), "NUL bytes"),
    "no section": (b"interface = virtual\n", "comes before any [section] line"),
    "a lone percent sign": (b"[default]\ninterface = virtual\nchannel = 50%\n", "a % must be written %%"),
    "a key twice": (b"[default]\ninterface = virtual\ninterface = kvaser\n", "interface twice in [default]"),
    "a line that is no setting": (b"[default]\ninterface = virtual\nPruefstand\n", "is not KEY = VALUE"),
    "a bad mark": (b"\xef\xbb\xbf[default]\n# Pr\xfcfstand\n", "byte-order mark"),
    "a folder": (None, "is a folder"),
}


@pytest.mark.parametrize("command", COMMANDS)
@pytest.mark.parametrize("damage", list(DAMAGED))
def test_a_config_file_that_cannot_be_read_is_refused_naming_it(damage: str, command: str, bench: WorkReached,
                                                                capsys: pytest.CaptureFixture[str]) -> None:
    content, words = DAMAGED[damage]
    path = Path(os.path.expanduser("~/.canrc"))
    if content is None:
        path.mkdir()
    else:
        path.write_bytes(content)
    completing = [] if command == "test" else ["--interface", "virtual"]
    code, out, err = run_cli([*BASE[command], *completing], capsys)
    assert code == ExitCode.RIG_ERROR and len(lines(err)) == 1 and "Traceback" not in err, err
    assert str(path) in err and words in err, err
    assert not bench.simulated and not bench.buses


@pytest.mark.parametrize(("value", "words"), [("{bad", "not JSON"), ("[1, 2]", "a JSON list, not an object")])
def test_a_can_config_that_is_not_a_json_object_is_refused_naming_it(value: str, words: str, bench: WorkReached,
                                                                     monkeypatch: pytest.MonkeyPatch,
                                                                     capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.setenv("CAN_CONFIG", value)
    code, out, err = run_cli(BASE["test"], capsys)
    assert code == ExitCode.RIG_ERROR and len(lines(err)) == 1 and "Traceback" not in err, err
    assert "CAN_CONFIG" in err and words in err, err
