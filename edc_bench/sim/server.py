"""The simulated rig as its own process, in real time, over slcan.

Serves the slcan protocol on a loopback TCP port (or a pseudo-terminal), so a
bench process drives it exactly as it would a USB-CAN adapter, for example
python-can's ``slcan`` interface with channel ``socket://127.0.0.1:PORT``.
Several hosts may connect at once; like nodes on one CAN bus, each sees the
frames of the rig and of the other hosts.

The plant advances lazily to the wall-clock time of each event (a frame, a
firmware deadline), so simulated physics stays in step with real time.

With an :class:`~edc_bench.sim.adapter.AdapterModel` (``edc-bench rig
--adapter usb-fs``) frames are held back as a USB CAN adapter holds them: a
host's command reaches the rig, and the rig's frames reach the hosts, only
when the adapter would deliver them.
"""

from __future__ import annotations

import ctypes
import gc
import math
import os
import selectors
import socket
import time
import tty
from collections import deque
from collections.abc import Callable

import numpy as np

from edc_bench.sim.adapter import AdapterModel
from edc_bench.sim.rig import SimulatedRig
from edc_bench.sim.slcan import SlcanDevice

_MAX_WAIT_S = 0.05


def reduce_timer_slack() -> bool:
    """Ask Linux for 1 ns timer slack so sleeps wake on time (best effort)."""
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        pr_set_timerslack = 29
        return libc.prctl(pr_set_timerslack, 1, 0, 0, 0) == 0
    except (OSError, AttributeError):
        return False


class _Host:
    """One connected host: its byte stream and slcan parser state."""

    def __init__(self, fd: int, write: Callable[[bytes], None], close: Callable[[], None], name: str) -> None:
        self.fd = fd
        self.write = write
        self.close = close
        self.name = name
        self.device = SlcanDevice()


class SlcanRigServer:
    """Runs a :class:`SimulatedRig` in real time behind slcan.

    Parameters
    ----------
    rig : SimulatedRig
        The rig to serve.
    clock_s : callable, optional
        Monotonic clock in seconds (``time.perf_counter`` by default).
    log : callable, optional
        Receives one line per connection event.
    """

    def __init__(self, rig: SimulatedRig, clock_s: Callable[[], float] = time.perf_counter,
                 log: Callable[[str], None] | None = None, adapter: AdapterModel | None = None) -> None:
        self.rig = rig
        self.adapter = adapter or AdapterModel()
        self._rng = np.random.default_rng([rig.seed, 0xADA])
        self._to_rig: deque[tuple[float, int, bytes]] = deque()
        self._to_hosts: deque[tuple[float, bytes]] = deque()
        self._last_to_rig = self._last_to_hosts = -math.inf
        #: the longest the serve loop went without looking at its sources (s): a measure of how disturbed it was
        self.worst_gap_s = 0.0
        self._clock = clock_s
        self._log = log or (lambda line: None)
        self._selector = selectors.DefaultSelector()
        self._hosts: dict[int, _Host] = {}
        self._t0 = 0.0
        self._stop = False
        #: Busy-poll while a host is connected (real-time fidelity at the cost of a core).
        self.poll_while_connected = True

    def stop(self) -> None:
        """Ask :meth:`serve_forever` to return (safe to call from a signal handler)."""
        self._stop = True

    def _now(self) -> float:
        return self._clock() - self._t0

    # -- sources ---------------------------------------------------------------
    def listen_tcp(self, host: str, port: int) -> tuple[str, int]:
        """Listen on ``host:port`` (port 0: any free port). Returns the bound address."""
        server = socket.create_server((host, port), reuse_port=False)
        server.setblocking(False)
        self._selector.register(server, selectors.EVENT_READ, ("listen", server))
        address = server.getsockname()
        return str(address[0]), int(address[1])

    def open_pty(self) -> str:
        """Serve on a new pseudo-terminal; returns the device path for the host."""
        master, slave = os.openpty()
        tty.setraw(slave)
        os.set_blocking(master, False)
        path = os.ttyname(slave)
        # keep the slave open so the master does not see EOF between hosts
        self._pty_slave = slave
        host = _Host(master, lambda data: _write_all(master, data), lambda: None, path)
        self._hosts[master] = host
        self._selector.register(master, selectors.EVENT_READ, ("host", host))
        return path

    def _accept(self, server: socket.socket) -> None:
        conn, peer = server.accept()
        conn.setblocking(True)
        conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        fd = conn.fileno()

        def close() -> None:
            self._selector.unregister(conn)
            conn.close()

        host = _Host(fd, conn.sendall, close, f"{peer[0]}:{peer[1]}")
        self._hosts[fd] = host
        self._selector.register(conn, selectors.EVENT_READ, ("host", host))
        self._log(f"host connected: {host.name}")

    def _read(self, host: _Host) -> None:
        try:
            data = os.read(host.fd, 4096)
        except (BlockingIOError, InterruptedError):
            return
        except OSError:
            data = b""
        if not data:
            self._log(f"host disconnected: {host.name}")
            del self._hosts[host.fd]
            host.close()
            return
        frames, reply = host.device.feed(data)
        if reply:
            self._safe_write(host, reply)
        for frame in frames:
            now = self._now()
            # other hosts on the bus see the frame too
            self._broadcast(SlcanDevice.format_frame(frame.can_id, frame.data, frame.extended), exclude=host)
            if frame.extended or frame.remote:
                continue
            if self.adapter.is_instant:
                for can_id, data_out in self.rig.receive(frame.can_id, frame.data, now):
                    self._broadcast(SlcanDevice.format_frame(can_id, data_out))
            else:
                self._last_to_rig = self.adapter.delivery_s(now, self._rng, self._last_to_rig)
                self._to_rig.append((self._last_to_rig, frame.can_id, bytes(frame.data)))

    def _from_rig(self, frames: list[tuple[int, bytes]], at_s: float) -> None:
        """Frames the rig sent at ``at_s``: to the hosts now, or when the adapter delivers them."""
        for can_id, data in frames:
            line = SlcanDevice.format_frame(can_id, data)
            if self.adapter.is_instant:
                self._broadcast(line)
            else:
                self._last_to_hosts = self.adapter.delivery_s(at_s, self._rng, self._last_to_hosts)
                self._to_hosts.append((self._last_to_hosts, line))

    def _deliver_due(self, now: float) -> None:
        """Adapter model: commands that have reached the rig, and the rig's frames that have reached the hosts."""
        while self._to_rig and self._to_rig[0][0] <= now:
            at_s, can_id, data = self._to_rig.popleft()
            self._from_rig(self.rig.receive(can_id, data, at_s), at_s)
        while self._to_hosts and self._to_hosts[0][0] <= now:
            self._broadcast(self._to_hosts.popleft()[1])

    def _safe_write(self, host: _Host, data: bytes) -> None:
        try:
            host.write(data)
        except OSError:
            pass  # a vanished host is noticed on its next read

    def _broadcast(self, line: bytes, exclude: _Host | None = None) -> None:
        for host in list(self._hosts.values()):
            if host is not exclude and host.device.is_open:
                self._safe_write(host, line)

    # -- loop ------------------------------------------------------------------
    def serve_forever(self) -> None:
        """Serve until :meth:`stop` is called."""
        reduce_timer_slack()
        # steps up to 5 ms cover any command rate of 200 Hz and more
        self.rig.plant.prepare(int(round(0.005 / self.rig.plant.quantum_s)))
        gc.collect()
        gc.freeze()  # what exists now is never scanned again: shorter collections
        self._t0 = self._clock()
        rig = self.rig
        last_s = self._now()
        while not self._stop:
            now = self._now()
            if self._hosts:
                self.worst_gap_s = max(self.worst_gap_s, now - last_s)
            last_s = now
            self._deliver_due(now)
            self._from_rig(rig.advance_to(now), now)
            if self._hosts and self.poll_while_connected:
                wait_s = 0.0  # poll: a sleeping process on a VM can wake milliseconds late
            else:
                wait_s = min(_MAX_WAIT_S, max(0.0, rig.firmware.next_deadline_s() - self._now()))
            for key, _ in self._selector.select(timeout=wait_s):
                kind, obj = key.data
                if kind == "listen":
                    self._accept(obj)
                else:
                    self._read(obj)
        for host in list(self._hosts.values()):
            host.close()
        self._selector.close()


def _write_all(fd: int, data: bytes) -> None:
    view = memoryview(data)
    while view:
        try:
            written = os.write(fd, view)
        except BlockingIOError:
            time.sleep(0.0001)
            continue
        view = view[written:]
