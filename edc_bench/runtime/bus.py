"""Opening and closing the bench's CAN bus, the python-can way, with a faster and stricter slcan reader.

python-can's ``slcan`` interface reads its serial stream one byte per call;
over ``socket://`` each byte costs a select and a recv (about 15 us here), so a
reply frame takes some 350 us to read and a 1 kHz loop falls behind as soon
as one reply is late. :class:`BufferedSlcanBus` is python-can's slcan bus
reading every byte waiting in one call, parsing every line strictly and
never raising on a bad one (python-can's parser raises on a bad hex digit or
a byte that is not ASCII). Socket channels also get TCP_NODELAY.

:class:`ClosingBus` closes any bus after a test without raising: a
connection that died during the test must not cost the record.
"""

from __future__ import annotations

import socket
import time
from collections import deque
from typing import Any

import can
from can.interfaces.slcan import slcanBus

from edc_bench.errors import RigError
from edc_bench.protocol.slcan import SlcanFrame, parse_frame_line


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
    """

    #: how long a send may wait for the peer to take the bytes: the rig's watchdog time, after which it is safe anyway
    send_timeout_s = 0.02
    _MAX_SAMPLES = 5
    _MAX_LINE = 64  # longer than any slcan frame line: a stream without terminators is junk

    def __init__(self, channel: str, **kwargs: Any) -> None:
        self.bad_lines = 0
        self.bad_line_samples: list[bytes] = []
        self.device_errors = 0
        self.shutdown_error: str | None = None
        self._lines: deque[bytes] = deque()
        super().__init__(channel, **kwargs)
        # a socket:// channel is read straight from its socket: pyserial's in_waiting says only 0 or 1 for it
        self._socket: socket.socket | None = getattr(self.serialPortOrig, "_socket", None)
        if self._socket is not None:
            self._socket.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)

    def _bad(self, line: bytes) -> None:
        self.bad_lines += 1
        if len(self.bad_line_samples) < self._MAX_SAMPLES:
            self.bad_line_samples.append(bytes(line[: self._MAX_LINE]))

    @staticmethod
    def _salvage(line: bytes) -> SlcanFrame | None:
        """A whole frame line at the end of a damaged one (noise glued to the next line), if there is one.

        No hex digit is one of ``tTrR``, so the last of them starts the frame if any does; the strict
        parser and the payload's CRC judge the rest.
        """
        start = max(line.rfind(kind) for kind in (b"t", b"T", b"r", b"R"))
        return parse_frame_line(line[start:]) if start > 0 else None

    def _split_lines(self) -> None:
        """Move every complete line of the buffer to the line queue (a BEL answer is a line of its own)."""
        buffer = self._buffer
        while True:
            ends = [i for i in (buffer.find(self._OK), buffer.find(self._ERROR)) if i >= 0]
            if not ends:
                if len(buffer) > self._MAX_LINE:
                    self._bad(buffer)
                    buffer.clear()
                return
            end = min(ends)
            if buffer[end : end + 1] == self._ERROR:
                self.device_errors += 1
                if end:
                    self._lines.append(bytes(buffer[:end]))
            else:
                self._lines.append(bytes(buffer[:end]))
            del buffer[: end + 1]

    def _read(self, timeout: float | None) -> bytes | None:
        """The next line (without its terminator), waiting at most ``timeout`` seconds; None if none came.

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
                    chunk = port.read(waiting) if self._socket is None else self._socket.recv(65536)
                    if not chunk:
                        raise OSError("connection closed by the other end")
                    self._buffer.extend(chunk)
                    self._split_lines()
                    if self._lines:
                        return self._lines.popleft()
                    continue
                if deadline.expired():
                    return None
                # nothing waiting: block for one byte, but only for the time left (pyserial's own timeout is fixed)
                left = deadline.time_left()
                if port.timeout != left:
                    port.timeout = left
                chunk = port.read(1)
                if chunk:
                    self._buffer.extend(chunk)
                    self._split_lines()
                    if self._lines:
                        return self._lines.popleft()
        except (serial.SerialException, OSError) as exc:
            raise can.CanOperationError(f"slcan stream failed: {exc}") from exc

    def _recv_internal(self, timeout: float | None) -> tuple[can.Message | None, bool]:
        import serial

        deadline = serial.Timeout(timeout)
        while True:
            line = self._read(deadline.time_left())
            if line is None:
                return None, False
            frame = parse_frame_line(line)
            if frame is None and line not in (b"z", b"Z", b""):  # not an acknowledgement of our own sends
                self._bad(line)
                frame = self._salvage(line)
            if frame is not None:
                return can.Message(arbitration_id=frame.can_id, is_extended_id=frame.extended,
                                   is_remote_frame=frame.remote, dlc=frame.length, data=frame.data,
                                   timestamp=time.time(), check=False), False
            if deadline.expired():
                return None, False

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        """Send ``msg``, waiting at most ``timeout`` (default :attr:`send_timeout_s`) for the peer to take it."""
        super().send(msg, self.send_timeout_s if timeout is None else timeout)

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

    def __enter__(self) -> can.BusABC:
        return self.bus

    def __exit__(self, *exc: object) -> None:
        self.close_error = close_quietly(self.bus)


def open_bus(config: dict[str, Any], default_bitrate: int) -> can.BusABC:
    """Open a python-can bus from ``interface``/``channel``/``bitrate`` settings.

    ``slcan`` gets :class:`BufferedSlcanBus`; on a ``socket://`` or pty
    channel it does not wait for an adapter to wake up.

    Raises
    ------
    RigError
        If the bus cannot be opened, naming the settings.
    """
    kwargs = dict(config)
    kwargs.setdefault("bitrate", default_bitrate)
    try:
        if kwargs.get("interface") == "slcan":
            kwargs.pop("interface")
            channel = str(kwargs.pop("channel", ""))
            if channel.startswith(("socket://", "/dev/pts")):
                kwargs.setdefault("sleep_after_open", 0)  # no USB adapter to wait for
            return BufferedSlcanBus(channel, **kwargs)
        return can.Bus(**kwargs)
    except (can.CanError, OSError, ValueError, ImportError) as exc:
        where = ", ".join(f"{k}={v}" for k, v in config.items())
        raise RigError(f"cannot open the CAN bus ({where}): {exc}") from None
