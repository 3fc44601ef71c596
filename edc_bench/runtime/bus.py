"""Opening the bench's CAN bus, the python-can way, with a faster slcan reader.

python-can's ``slcan`` interface reads its serial stream one byte per call;
over ``socket://`` each byte costs a select and a recv (about 15 us here), so a
reply frame takes some 350 us to read and a 1 kHz loop falls behind as soon
as one reply is late. :class:`BufferedSlcanBus` is python-can's slcan bus
with one change: it reads every byte waiting in one call and hands complete
lines beyond the first to python-can's own line queue. Protocol handling
stays python-can's. Socket channels also get TCP_NODELAY.
"""

from __future__ import annotations

import socket
from typing import Any

import can
from can.interfaces.slcan import slcanBus

from edc_bench.errors import RigError


class BufferedSlcanBus(slcanBus):
    """python-can's slcan bus, reading all waiting bytes at once."""

    def __init__(self, channel: str, **kwargs: Any) -> None:
        super().__init__(channel, **kwargs)
        sock = getattr(self.serialPortOrig, "_socket", None)
        if sock is not None:
            sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)

    def _pop_line(self) -> str | None:
        buffer = self._buffer
        first = None
        while True:
            ends = [i for i in (buffer.find(self._OK), buffer.find(self._ERROR)) if i >= 0]
            if not ends:
                return first
            end = min(ends) + 1
            line = buffer[:end].decode()
            del buffer[:end]
            if first is None:
                first = line
            else:
                self._queue.put(line)

    def _read(self, timeout: float | None) -> str | None:
        import serial

        deadline = serial.Timeout(timeout)
        port = self.serialPortOrig
        while True:
            line = self._pop_line()
            if line is not None:
                return line
            waiting = port.in_waiting
            if waiting > 0:
                self._buffer.extend(port.read(waiting))
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
