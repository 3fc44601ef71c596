"""The simulated rig behind slcan on a real loopback TCP connection, stepped in simulated time.

For tests of the bench's slcan path as it runs against ``edc-bench rig`` or a
USB-CAN adapter (python-can's slcan bus, pyserial's ``socket://``, the bytes
on a socket), but deterministic: the bench's
:class:`~edc_bench.runtime.clock.SimulatedClock` steps this rig, which reads
the bench's lines from its end of the connection and writes the rig's frames
back, as :class:`~edc_bench.sim.inprocess.InProcessRig` does on a python-can
bus. It can misbehave at a given time: write any bytes (a line that is not
ASCII, an extended frame, another host's command), or drop the connection.

Example
-------
::

    link = SlcanSocketRig(SimulatedRig(variant, spec, seed=1))
    with ClosingBus(open_bus({"interface": "slcan", "channel": link.channel}, 500000)) as bus:
        link.accept()
        link.at(2.5, link.disconnect)
        result = run_bench_test(bus, SimulatedClock(link), variant)
"""

from __future__ import annotations

import select
import socket
from collections.abc import Callable

from edc_bench.protocol.slcan import SlcanFrame, format_frame_line
from edc_bench.sim.rig import SimulatedRig
from edc_bench.sim.slcan import SlcanDevice

#: how long the rig waits for a line the bench has just sent (never reached on loopback unless the bench is gone)
_LINE_WAIT_S = 1.0


class SlcanSocketRig:
    """A :class:`SimulatedRig` serving slcan on a loopback TCP port, in lockstep.

    Parameters
    ----------
    rig : SimulatedRig
        The rig behind the connection.

    Attributes
    ----------
    channel : str
        The python-can slcan channel to open (``socket://127.0.0.1:PORT``).
    bytes_from_bench : bytearray
        Everything the bench wrote, for assertions.
    """

    def __init__(self, rig: SimulatedRig) -> None:
        self.rig = rig
        self.device = SlcanDevice()
        self._listener = socket.create_server(("127.0.0.1", 0))
        self.channel = f"socket://127.0.0.1:{self._listener.getsockname()[1]}"
        self._conn: socket.socket | None = None
        self._actions: list[tuple[float, Callable[[], None]]] = []
        self.bytes_from_bench = bytearray()

    def accept(self) -> None:
        """Take the bench's connection (after it opened its bus, which connects without waiting)."""
        self._listener.settimeout(5.0)
        self._conn, _ = self._listener.accept()
        self._conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self._listener.close()

    # -- misbehaviour ----------------------------------------------------------------------------------------------
    def at(self, t_s: float, action: Callable[[], None]) -> None:
        """Run ``action`` once simulated time reaches ``t_s``."""
        self._actions.append((t_s, action))
        self._actions.sort(key=lambda entry: entry[0])

    def write(self, data: bytes) -> None:
        """Write raw bytes to the bench, as the rig's adapter would."""
        if self._conn is not None:
            try:
                self._conn.sendall(data)
            except OSError:
                self.disconnect()

    def write_frame(self, can_id: int, data: bytes, extended: bool = False) -> None:
        """Write one well-formed frame line (another node's frame)."""
        self.write(format_frame_line(SlcanFrame(can_id, bytes(data), extended)))

    def disconnect(self) -> None:
        """Drop the connection: a TCP link cut, an adapter unplugged."""
        if self._conn is not None:
            try:
                self._conn.shutdown(socket.SHUT_RDWR)
            except OSError:
                pass
            self._conn.close()
            self._conn = None

    # -- lockstep (what SimulatedClock calls) ----------------------------------------------------------------------
    def service(self, now_s: float) -> None:
        """The bench has sent a line: wait for it, let the rig answer."""
        self._take(now_s, wait_s=_LINE_WAIT_S)

    def advance_to(self, t_s: float) -> None:
        """Let simulated time pass to ``t_s``: scheduled misbehaviour, the rig's own frames."""
        while self._actions and self._actions[0][0] <= t_s:
            _, action = self._actions.pop(0)
            action()
        self._take(t_s, wait_s=0.0)
        self._send(self.rig.advance_to(t_s))

    def _send(self, frames: list[tuple[int, bytes]]) -> None:
        for can_id, data in frames:
            self.write(SlcanDevice.format_frame(can_id, data))

    def _take(self, now_s: float, wait_s: float) -> None:
        """Read what the bench wrote (waiting up to ``wait_s`` for a whole line); the rig acts on its frames."""
        conn = self._conn
        while conn is not None:
            ready, _, _ = select.select([conn], [], [], wait_s)
            if not ready:
                return
            try:
                data = conn.recv(65536)
            except OSError:
                data = b""
            if not data:
                self.disconnect()
                return
            self.bytes_from_bench += data
            frames, reply = self.device.feed(data)
            if reply:
                self.write(reply)
            for frame in frames:
                if not (frame.extended or frame.remote):
                    self._send(self.rig.advance_to(now_s))
                    self._send(self.rig.receive(frame.can_id, frame.data, now_s))
            if reply:
                wait_s = 0.0  # a whole line came: take what else is there, but wait no longer
