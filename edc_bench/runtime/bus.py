"""Opening and closing the bench's CAN bus, the python-can way, with a faster and stricter slcan reader.

python-can's ``slcan`` interface reads its serial stream one byte per call;
over ``socket://`` each byte costs a select and a recv, so reading one reply
frame takes a good part of a 1 kHz tick and the loop falls behind as soon as
one reply is late (``edc-bench perf --only realtime`` times the loop over
the rig's socket). :class:`BufferedSlcanBus` is python-can's slcan bus
reading every byte waiting in one call, parsing every line strictly and
never raising on a bad one (python-can's parser raises on a bad hex digit or
a byte that is not ASCII). Socket channels also get TCP_NODELAY.

:class:`ClosingBus` closes any bus after a test without raising: a
connection that died during the test must not cost the record.
"""

from __future__ import annotations

import os
import select
import socket
import time
from collections import deque
from collections.abc import Mapping
from typing import Any

from edc_bench.canlib import can  # isort: skip - first: python-can without its MF4 support (see canlib)
from can.interfaces.slcan import slcanBus

from edc_bench.errors import RigError
from edc_bench.protocol.slcan import MAX_LINE, parse_frame_line
from edc_bench.runtime.adapter_counts import AdapterCounts

#: slcan's line ends: CR after a line, BEL for an error answer (its own here: python-can's are private)
_CR, _BEL = b"\r", b"\a"


class BufferedSlcanBus(slcanBus):
    """python-can's slcan bus, reading all waiting bytes at once and trusting no line.

    Every line the adapter sends is parsed strictly
    (:func:`~edc_bench.protocol.slcan.parse_frame_line`): a damaged or unknown
    line (a byte that is not ASCII, a bad hex digit, trailing junk) is counted
    in :attr:`bad_lines` and skipped, never raised, so one bad byte from the
    rig cannot end a test or the safe stop after it. A stream that fails
    (the adapter or the TCP connection gone) raises :class:`can.CanOperationError`,
    as python-can's buses do. Sends give up after :attr:`send_timeout_s`
    instead of blocking on a peer that stopped reading, and :meth:`shutdown`
    never raises: closing a dead connection must not cost the record.

    Attributes
    ----------
    bad_lines : int
        Lines that were not valid frames, device acknowledgements or errors.
    bad_line_samples : list of bytes
        The first few of them, for the record.
    device_errors : int
        BEL (error) answers of the adapter.
    shutdown_error : str or None
        Why closing the connection failed, if it did.

    python-can's slcan bus is used through its public interface (its constructor opens the port and sets the
    bitrate; ``serialPortOrig`` is the port) and one hook: it writes every line through ``_write``, overridden
    here so that a send is given up only when bytes are left unsent (see :meth:`_write`). A ``socket://`` port is
    read straight from pyserial's socket (``_socket``: pyserial offers no other way to read all waiting bytes).
    """

    #: how long a send may wait for the peer to take the bytes: the rig's watchdog time, after which it is safe anyway
    send_timeout_s = 0.02
    _MAX_SAMPLES = 5

    def __init__(self, channel: str, **kwargs: Any) -> None:
        self.bad_lines = 0
        self.bad_line_samples: list[bytes] = []
        self.device_errors = 0
        self.shutdown_error: str | None = None
        self._lines: deque[bytes] = deque()
        self._pending = bytearray()  # bytes read but not yet a whole line
        self._discarding = False  # dropping the rest of an overlong line
        super().__init__(channel, **kwargs)
        # a socket:// channel is read straight from its socket: pyserial's in_waiting says only 0 or 1 for it
        self._socket: socket.socket | None = getattr(self.serialPortOrig, "_socket", None)
        if self._socket is not None:
            self._socket.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)

    def adapter_counts(self) -> AdapterCounts:
        """What was skipped so far (:class:`~edc_bench.runtime.adapter_counts.CountsAdapterErrors`)."""
        return AdapterCounts(self.bad_lines, tuple(self.bad_line_samples), self.device_errors)

    def _bad(self, line: bytes) -> None:
        self.bad_lines += 1
        if len(self.bad_line_samples) < self._MAX_SAMPLES:
            self.bad_line_samples.append(bytes(line[:MAX_LINE]))

    @staticmethod
    def _frame_tail(line: bytes) -> bytes:
        """Where a frame line could start at the end of a damaged line (noise glued to the next line).

        No hex digit is one of ``tTrR``, so the last of them starts the frame if any does; the strict
        parser and the payload's CRC judge the rest. Empty if there is none after the first byte.
        """
        start = max(line.rfind(b"t"), line.rfind(b"T"), line.rfind(b"r"), line.rfind(b"R"))
        return line[start:] if start > 0 else b""

    def _split_lines(self) -> None:
        """Move every complete line of the buffer to the line queue (a BEL answer ends a line too)."""
        buffer = self._pending
        while True:
            cr, bel = buffer.find(_CR), buffer.find(_BEL)
            end = cr if bel < 0 or 0 <= cr < bel else bel
            if end < 0:
                if len(buffer) > MAX_LINE:  # noise without a line end: counted once, dropped up to the next end
                    self._bad(buffer)
                    buffer.clear()
                    self._discarding = True
                return
            line = bytes(buffer[:end]).lstrip(b"\n")  # an adapter ending its lines with CR LF
            if end == bel:
                self.device_errors += 1
            del buffer[: end + 1]
            if self._discarding:  # the rest of an overlong line: only a frame line at its end is kept
                self._discarding = False
                line = self._frame_tail(line)
            if line:
                self._lines.append(line)

    def flush(self) -> None:
        """Drop what was read but not yet taken, and the port's input (python-can's flush)."""
        self._pending.clear()
        self._lines.clear()
        super().flush()

    def _take(self, chunk: bytes) -> None:
        self._pending.extend(chunk)
        self._split_lines()

    def _read_line(self, timeout: float | None) -> bytes | None:
        """The next line (without its terminator), waiting at most ``timeout`` seconds; None if none came.

        A peer that keeps sending bytes but no line end cannot hold the reader past ``timeout``.

        Raises
        ------
        can.CanOperationError
            If the stream failed (adapter unplugged, connection closed).
        """
        import serial

        if self._lines:
            return self._lines.popleft()
        deadline = serial.Timeout(timeout)
        port = self.serialPortOrig
        try:
            while True:
                waiting = port.in_waiting
                if waiting > 0:
                    if self._socket is None:
                        self._take(port.read(waiting))
                    else:
                        chunk = self._socket.recv(65536)
                        if not chunk:
                            raise OSError("connection closed by the other end")
                        self._take(chunk)
                elif not deadline.expired():
                    # nothing waiting: block for one byte, but only for the time left (pyserial's timeout is fixed)
                    left = deadline.time_left()
                    if port.timeout != left:
                        port.timeout = left
                    self._take(port.read(1))
                if self._lines:
                    return self._lines.popleft()
                if deadline.expired():
                    return None
        except (serial.SerialException, OSError) as exc:
            raise can.CanOperationError(f"slcan stream failed: {exc}") from exc

    def _recv_internal(self, timeout: float | None) -> tuple[can.Message | None, bool]:
        import serial

        deadline = serial.Timeout(timeout)
        while True:
            line = self._read_line(deadline.time_left())
            if line is None:
                return None, False
            frame = parse_frame_line(line)
            if frame is None and line not in (b"z", b"Z"):  # not an acknowledgement of our own sends
                self._bad(line)
                frame = parse_frame_line(self._frame_tail(line))
            if frame is not None:
                return can.Message(arbitration_id=frame.can_id, is_extended_id=frame.extended,
                                   is_remote_frame=frame.remote, dlc=frame.length, data=frame.data,
                                   timestamp=time.time(), check=False), False
            if deadline.expired() and not self._lines:  # lines already read are taken at once, whatever the time
                return None, False

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        """Send ``msg``, waiting at most ``timeout`` (default :attr:`send_timeout_s`) for the peer to take it."""
        super().send(msg, self.send_timeout_s if timeout is None else timeout)

    def _write(self, string: str) -> None:
        """Write one line (python-can's send calls this); given up only when bytes are still unsent at the send's
        deadline.

        pyserial's own write looks at the clock after its write and raises its timeout once the time is past, even
        when every byte went out: a bench that a busy PC held off the CPU for 20 ms lost its test to a "write
        timeout" of a line that had been sent. A socket or a POSIX port
        is written here; any other port (Windows) by pyserial as before.
        """
        port = self.serialPortOrig
        if not hasattr(self, "_socket"):  # the adapter's set-up lines, written while python-can opens the bus
            super()._write(string)
            return
        target: Any = self._socket if self._socket is not None else getattr(port, "fd", None)
        if target is None:
            super()._write(string)
            return
        data = memoryview(string.encode() + self.LINE_TERMINATOR)
        timeout_s = port.write_timeout
        deadline = None if timeout_s is None else time.monotonic() + timeout_s
        try:
            while data:
                try:
                    sent = self._socket.send(data) if self._socket is not None else os.write(target, data)
                except BlockingIOError:
                    sent = 0
                data = data[sent:]
                if not data:
                    return
                left = None if deadline is None else deadline - time.monotonic()
                if left is not None and left <= 0:
                    raise can.CanOperationError(f"slcan send gave up: the adapter took no more bytes within "
                                                f"{timeout_s * 1e3:g} ms ({len(data)} left unsent)")
                select.select([], [target], [], left)
        except OSError as exc:
            raise can.CanOperationError(f"slcan stream failed: {exc}") from exc

    def shutdown(self) -> None:
        """Close the channel and the port; a connection that is already gone is noted, not raised."""
        try:
            super().shutdown()
        except (can.CanError, OSError, ValueError) as exc:
            self.shutdown_error = f"{type(exc).__name__}: {exc}"
            try:
                self.serialPortOrig.close()
            except Exception:  # noqa: BLE001, S110 - the port is being abandoned either way
                pass


def close_quietly(bus: can.BusABC) -> str | None:
    """Shut ``bus`` down; why that failed (None if it did not). Never raises."""
    try:
        bus.shutdown()
    except Exception as exc:  # noqa: BLE001 - any interface's error on closing a dead connection
        return f"{type(exc).__name__}: {exc}"
    return getattr(bus, "shutdown_error", None)


class ClosingBus:
    """``with ClosingBus(open_bus(...)) as bus:``: the bus, closed on leaving without ever raising.

    Attributes
    ----------
    close_error : str or None
        Why closing failed, for the record (the test's data is safe either way).
    """

    def __init__(self, bus: can.BusABC) -> None:
        self.bus = bus
        self.close_error: str | None = None
        self.closed = False

    def __enter__(self) -> can.BusABC:
        return self.bus

    def __exit__(self, *exc: object) -> None:
        if not self.closed:  # closed once: a bus opened ahead of its test is closed by the test, or after it
            self.closed = True
            self.close_error = close_quietly(self.bus)


def open_bus(config: Mapping[str, Any], default_bitrate: int) -> can.BusABC:
    """Open a python-can bus from its settings (``interface``, ``channel``, ``bitrate`` and any further argument).

    The settings are complete (:func:`edc_bench.cli.common.bus_settings` reads python-can's environment and
    config files robustly): python-can is told to read no config of its own, which it would read in the
    locale's encoding. ``slcan`` gets :class:`BufferedSlcanBus`; on a ``socket://`` or pty channel it does not
    wait for an adapter to wake up. What python-can and the driver log while the bus opens is held back: a bus
    that does not open is said in one line, and one that opens lets it out.

    Raises
    ------
    RigError
        If the bus cannot be opened, whatever the driver raised: one line naming the settings, why, and what
        the interface needs (a driver to install, a channel or argument to give).
    """
    from edc_bench.runtime.bus_config import (
        bus_problem,
        exception_words,
        python_can_voice,
        replay_said_on_import,
    )

    bus: can.BusABC | None = None
    refused: str | None = None
    why = ""
    with python_can_voice() as voice:
        try:
            bus = _open(config, default_bitrate)
        except RigError as exc:  # said in full already
            refused = str(exc)
        except Exception as exc:  # noqa: BLE001 - whatever a driver raises (NameError of a missing library...)
            why = exception_words(exc)
        # a bus that failed half-way is gone here (its destructor's warning held back, not printed after the line)
    if refused is not None:
        raise RigError(refused)
    if bus is None:
        raise RigError(bus_problem(config, why, voice.lines()))
    voice.replay()
    replay_said_on_import(str(config.get("interface")))
    return bus


def _open(config: Mapping[str, Any], default_bitrate: int) -> can.BusABC:
    """Open the bus; RigError (one line) for what is known before python-can is asked, anything for the rest."""
    from edc_bench.runtime.bus_config import bus_keyword_arguments, bus_problem, check_interface

    check_interface(config)  # bus_settings did for the commands; here for every other caller too (cached import)
    interface = str(config.get("interface"))
    kwargs = bus_keyword_arguments({**config, "bitrate": config.get("bitrate") or default_bitrate})
    if interface == "socketcand":
        problem = socketcand_problem(kwargs.get("host"), kwargs.get("port"))
        if problem:
            raise RigError(bus_problem(config, problem, channel=False))
    if interface == "slcan":
        kwargs.pop("interface")
        channel = str(kwargs.pop("channel", ""))
        if channel.startswith(("socket://", "/dev/pts")):
            kwargs.setdefault("sleep_after_open", 0)  # no USB adapter to wait for
        return BufferedSlcanBus(channel, **kwargs)
    return can.Bus(ignore_config=True, **kwargs)


#: How long a socketcand server may take to accept the connection and to greet.
SOCKETCAND_TIMEOUT_S = 3.0


def socketcand_problem(host: Any, port: Any) -> str | None:
    """Why no socketcand server greets at ``host``:``port`` (None if one does), found within
    :data:`SOCKETCAND_TIMEOUT_S`.

    python-can's socketcand bus retries a refused connection for 10 s, logging each attempt, and waits without
    limit for a server that accepts and says nothing; a look first makes those one line in a few seconds.
    """
    if not isinstance(port, int) or not 0 < port < 65536:
        return f"--bus-option port={port}: not a port number; give socketcand's TCP port, 1 to 65535 (its default 29536)"
    address = f"{host}:{port}"
    try:
        sock = socket.create_connection((str(host), port), timeout=SOCKETCAND_TIMEOUT_S)
    except socket.gaierror as exc:
        return f"socketcand host {host!r} is not known here ({exc.strerror}); give its name or address"
    except ConnectionRefusedError:
        return (f"nothing listens at {address} (connection refused): start socketcand there (e.g. socketcand -i can0), "
                "or give its --bus-option host= and port=")
    except TimeoutError:
        return (f"{address} did not answer within {SOCKETCAND_TIMEOUT_S:g} s: is the host up, socketcand running "
                "there and the network between?")
    except OSError as exc:
        return f"cannot reach {address} ({exc.strerror or exc})"
    greeting = b""
    with sock:
        try:
            while b">" not in greeting and len(greeting) < 64:
                chunk = sock.recv(64)
                if not chunk:
                    break
                greeting += chunk
        except TimeoutError:
            return (f"{address} accepted the connection but said nothing within {SOCKETCAND_TIMEOUT_S:g} s (socketcand "
                    "greets at once): is it socketcand's port?")
        except OSError as exc:
            return f"{address} dropped the connection ({exc.strerror or exc}): is it socketcand's port?"
    text = greeting.decode("ascii", "replace").strip()
    if not text.startswith("< hi >"):
        return f"{address} is not a socketcand server: it greeted {text[:40]!r}, not '< hi >'; check the port"
    return None
