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

Hosts are not trusted to behave (docs/simulation.md, "The rig server under
hostile hosts"): the server never blocks on a host (each has a bounded
output queue; what does not fit is dropped and counted, as an adapter
overflows), takes only exactly-formed slcan lines, forwards remote frames as
remote frames, and lets one host at a time command the rig.
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
from dataclasses import dataclass

import numpy as np

from edc_bench.protocol import BENCH_CMD_ID, Mode, ProtocolError, RigState
from edc_bench.protocol.slcan import SlcanFrame, format_frame_line
from edc_bench.sim.adapter import AdapterModel
from edc_bench.sim.rig import SimulatedRig
from edc_bench.sim.slcan import SlcanDevice

_MAX_WAIT_S = 0.05
#: Bytes queued for a host that does not read before lines for it are dropped: about a second of a 1 kHz test's
#: traffic to one host (one or two lines of some 22 bytes a tick; docs/simulation.md prints the span), longer than a bench's 300 ms heartbeat rule
#: tolerates; the kernel's socket buffer comes on top. A USB adapter buffers far less.
HOST_QUEUE_BYTES = 32768
#: A rig READY whose owner has sent no BENCH_CMD for this long (s) is free for another host's test.
OWNER_IDLE_S = 1.0


def reduce_timer_slack() -> bool:
    """Ask Linux for 1 ns timer slack so sleeps wake on time (best effort)."""
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        pr_set_timerslack = 29
        return libc.prctl(pr_set_timerslack, 1, 0, 0, 0) == 0
    except (OSError, AttributeError):
        return False


@dataclass(frozen=True)
class HostStats:
    """What the server counted for one connected host.

    Attributes
    ----------
    name : str
        The host (peer address, pty path, or the name it was added with).
    dropped_lines : int
        Lines for the host dropped because its output queue was full (it did not read).
    malformed_lines : int
        Lines from the host answered BEL: malformed, unknown or too long.
    refused_bench_cmds : int
        ``BENCH_CMD`` frames refused because another host owned the rig.
    """

    name: str
    dropped_lines: int
    malformed_lines: int
    refused_bench_cmds: int


class _Host:
    """One connected host: its byte streams, slcan parser state and counters.

    What the server writes to a host goes through a bounded queue and is sent
    without blocking; lines that do not fit are dropped whole, so the host's
    stream stays a sequence of complete lines.
    """

    def __init__(self, fileobj: socket.socket | int, send: Callable[[bytes | bytearray], int],
                 close: Callable[[], None], name: str, queue_bytes: int) -> None:
        self.fileobj = fileobj
        self.fd = fileobj if isinstance(fileobj, int) else fileobj.fileno()
        self.close = close
        self.name = name
        self.device = SlcanDevice()
        self.pending = bytearray()  # queued for the host, not yet taken by the kernel
        self.watching_writes = False  # registered for EVENT_WRITE while something is pending
        self.dropped_lines = 0
        self.refused_bench_cmds = 0
        self.told_full = False  # a full queue and a refusal are logged once per host
        self.told_refused = False
        self.last_bench_cmd_s = -math.inf
        self._send = send
        self._queue_bytes = queue_bytes
        self._broken = False

    def queue(self, data: bytes) -> bool:
        """Queue whole lines for the host and send what the kernel takes now; False if they were dropped."""
        if self._broken:
            return True  # a vanished host is noticed on its next read
        if len(self.pending) + len(data) > self._queue_bytes:
            self.dropped_lines += data.count(b"\r") + data.count(b"\a")
            self.device.overrun = True  # the host can read it from its status flags (F)
            return False
        waiting = bool(self.pending)
        self.pending += data
        if not waiting:  # else the selector says when the host takes more
            self.flush()
        return True

    def flush(self) -> None:
        """Send what the kernel takes without blocking."""
        while self.pending:
            try:
                sent = self._send(self.pending)
            except (BlockingIOError, InterruptedError):
                return
            except OSError:
                self._broken = True
                self.pending.clear()
                return
            del self.pending[:sent]

    def stats(self) -> HostStats:
        """The host's counters."""
        return HostStats(self.name, self.dropped_lines, self.device.errors, self.refused_bench_cmds)


class SlcanRigServer:
    """Runs a :class:`SimulatedRig` in real time behind slcan.

    Parameters
    ----------
    rig : SimulatedRig
        The rig to serve.
    clock_s : callable, optional
        Monotonic clock in seconds (``time.perf_counter`` by default).
    log : callable, optional
        Receives one line per connection event, and once per host for a
        host that does not read or whose ``BENCH_CMD`` is refused.
    adapter : AdapterModel, optional
        The CAN adapter's timing between hosts and rig; instant by default.
    host_queue_bytes : int, optional
        Bytes queued for a host that does not take them before further lines
        for it are dropped (:data:`HOST_QUEUE_BYTES` by default).
    """

    def __init__(self, rig: SimulatedRig, clock_s: Callable[[], float] = time.perf_counter,
                 log: Callable[[str], None] | None = None, adapter: AdapterModel | None = None,
                 host_queue_bytes: int = HOST_QUEUE_BYTES) -> None:
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
        self._host_queue_bytes = host_queue_bytes
        self._selector = selectors.DefaultSelector()
        self._hosts: dict[int, _Host] = {}
        self._owner: _Host | None = None  # the host whose BENCH_CMDs reach the rig
        self._t0 = 0.0
        self._last_s: float | None = None  # when the last pass began
        self._asleep_s = 0.0  # how long the last pass slept in select, within the wait it asked for
        self._stop = False
        #: Busy-poll while a host is connected (real-time fidelity at the cost of a core): a sleeping process
        #: on a VM can wake milliseconds late. Not under a real-time policy, where a wake-up preempts at once and
        #: a spinning rig would only take the core from the bench's loop (and hit the kernel's real-time
        #: throttling, which then stops the rig for 50 ms in every second).
        self.poll_while_connected = not running_realtime()

    def stop(self) -> None:
        """Ask :meth:`serve_forever` to return (safe to call from a signal handler)."""
        self._stop = True

    def host_stats(self) -> list[HostStats]:
        """What the server counted for each connected host (dropped, malformed, refused)."""
        return [host.stats() for host in self._hosts.values()]

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
        self._add(_Host(master, lambda data: os.write(master, data), lambda: None, path, self._host_queue_bytes))
        return path

    def _accept(self, server: socket.socket) -> None:
        conn, peer = server.accept()
        conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self.add_host(conn, f"{peer[0]}:{peer[1]}")

    def add_host(self, conn: socket.socket, name: str) -> None:
        """Serve a host on a connected stream socket (an accepted connection, or one end of a socketpair).

        Parameters
        ----------
        conn : socket.socket
            The connection; the server makes it non-blocking and closes it when the host goes.
        name : str
            The host's name in the log and in :meth:`host_stats`.
        """
        conn.setblocking(False)  # a host that does not read must never hold up the loop

        def close() -> None:
            self._selector.unregister(conn)
            conn.close()

        self._add(_Host(conn, conn.send, close, name, self._host_queue_bytes))
        self._log(f"host connected: {name}")

    def _add(self, host: _Host) -> None:
        if not self._hosts:  # the serve gap counts while a host is connected: from now, not from the idle wait
            self._last_s = self._now()
        self._hosts[host.fd] = host
        self._selector.register(host.fileobj, selectors.EVENT_READ, ("host", host))

    def _remove(self, host: _Host) -> None:
        counts = host.stats()
        noted = [f"{n} {what}" for n, what in ((counts.dropped_lines, "lines dropped"),
                                                (counts.malformed_lines, "lines refused"),
                                                (counts.refused_bench_cmds, "BENCH_CMD refused")) if n]
        self._log(f"host disconnected: {host.name}" + (f" ({', '.join(noted)})" if noted else ""))
        if self._owner is host:
            self._owner = None  # the rig is free for the next host at once
        del self._hosts[host.fd]
        host.close()

    def _read(self, host: _Host) -> None:
        try:
            data = os.read(host.fd, 4096)
        except (BlockingIOError, InterruptedError):
            return
        except OSError:
            data = b""
        if not data:
            self._remove(host)
            return
        now = self._now()
        frames, reply = host.device.feed(data, admit=lambda frame: self._admit(host, frame, now))
        if reply:
            self._write(host, reply)
        for frame in frames:
            self._on_bus(host, frame, now)

    def _on_bus(self, sender: _Host, frame: SlcanFrame, now: float) -> None:
        """A frame a host put on the bus: the other hosts see it, the rig gets it."""
        self._broadcast(format_frame_line(frame), exclude=sender)  # a remote frame stays one, with its DLC
        if frame.extended or frame.remote:
            return  # the rig's ICD has standard data frames only
        if self.adapter.is_instant:
            self._from_rig(self.rig.receive(frame.can_id, frame.data, now), now)
        else:
            self._last_to_rig = self.adapter.delivery_s(now, self._rng, self._last_to_rig)
            self._to_rig.append((self._last_to_rig, frame.can_id, bytes(frame.data)))

    # -- who commands the rig --------------------------------------------------
    def _admit(self, host: _Host, frame: SlcanFrame, now: float) -> bool:
        """Whether a host's frame goes on the bus: a ``BENCH_CMD`` only from the host that owns the rig.

        The first host to send a ``BENCH_CMD`` owns the rig until it disconnects, or until its test is over
        (:meth:`_owner_is_done`); another host's ``BENCH_CMD`` is answered BEL and reaches nobody.
        """
        if frame.can_id != BENCH_CMD_ID or frame.extended or frame.remote:
            return True
        owner = self._owner
        if owner is not None and owner is not host and not self._owner_is_done(owner, now):
            host.refused_bench_cmds += 1
            if not host.told_refused:
                host.told_refused = True
                self._log(f"host {host.name}: BENCH_CMD refused, the rig is owned by {owner.name}")
            return False
        if owner is not host:
            if not self._obeyable(frame.data):
                return True  # the rig refuses it (bad CRC, undefined Mode): delivered, but it wins no ownership
            self._owner = host
            self._log(f"host {host.name}: owns the rig")
        host.last_bench_cmd_s = now
        return True

    def _obeyable(self, payload: bytes) -> bool:
        """Whether the rig would obey this ``BENCH_CMD`` payload (CRC and Mode as the firmware checks them)."""
        try:
            return self.rig.firmware.icd.parse_bench_cmd(payload).mode in (Mode.SAFE, Mode.RUN)
        except ProtocolError:
            return False

    def _owner_is_done(self, owner: _Host, now: float) -> bool:
        """The owner's test is over: the rig READY (amplifier off) and no ``BENCH_CMD`` from it for a while.

        Only a SAFE command brings a rig that ran back to READY, so READY with the owner quiet for
        :data:`OWNER_IDLE_S` is a finished test; a rig left RUNNING or in FAULT stays its owner's.
        """
        return self.rig.firmware.state is RigState.READY and now - owner.last_bench_cmd_s >= OWNER_IDLE_S

    # -- to the hosts ----------------------------------------------------------
    def _from_rig(self, frames: list[tuple[int, bytes]], at_s: float) -> None:
        """Frames the rig sent at ``at_s``: to the hosts now, or when the adapter delivers them."""
        for can_id, data in frames:
            line = SlcanDevice.format_frame(can_id, data)
            if self.adapter.is_instant:
                self._broadcast(line)
            else:
                self._last_to_hosts = self.adapter.delivery_s(at_s, self._rng, self._last_to_hosts)
                self._to_hosts.append((self._last_to_hosts, line))

    def _next_due_s(self) -> float:
        """When the rig next has something to do: its firmware's next deadline, or a frame the adapter holds (a
        USB adapter delivers in its own frames). Sleeping past a held frame delivered each reply only when the next
        command woke the loop: under SCHED_FIFO (no polling), every reply came one command late."""
        due = self.rig.firmware.next_deadline_s()
        if self._to_rig:
            due = min(due, self._to_rig[0][0])
        if self._to_hosts:
            due = min(due, self._to_hosts[0][0])
        return due

    def _deliver_due(self, now: float) -> None:
        """Adapter model: commands that have reached the rig, and the rig's frames that have reached the hosts."""
        while self._to_rig and self._to_rig[0][0] <= now:
            at_s, can_id, data = self._to_rig.popleft()
            self._from_rig(self.rig.receive(can_id, data, at_s), at_s)
        while self._to_hosts and self._to_hosts[0][0] <= now:
            self._broadcast(self._to_hosts.popleft()[1])

    def _write(self, host: _Host, data: bytes) -> None:
        """Queue whole lines for a host; never blocks.

        A host that does not take what it is sent loses frames as a CAN
        adapter's host does when the adapter's buffer overflows: lines that
        do not fit its queue are dropped and counted, and its status flags
        (``F``) report a data overrun. It is not disconnected: a host that was
        only held up (a VM stall, a debugger, a pause) reads on, sees the gaps
        (counters, heartbeats) and its own fault rules decide, while the rig
        and the other hosts go on in real time.
        """
        if not host.queue(data) and not host.told_full:
            host.told_full = True
            self._log(f"host {host.name}: not reading; output queue full at {self._host_queue_bytes} bytes, "
                      "dropping its frames as an adapter overflows")
        self._watch_writes(host)

    def _flush(self, host: _Host) -> None:
        host.flush()
        self._watch_writes(host)

    def _watch_writes(self, host: _Host) -> None:
        """Ask the selector about the host's room to write only while something waits for it."""
        wanted = bool(host.pending)
        if wanted != host.watching_writes and host.fd in self._hosts:
            events = selectors.EVENT_READ | (selectors.EVENT_WRITE if wanted else 0)
            self._selector.modify(host.fileobj, events, ("host", host))
            host.watching_writes = wanted

    def _broadcast(self, line: bytes, exclude: _Host | None = None) -> None:
        for host in list(self._hosts.values()):
            if host is not exclude and host.device.is_open:
                self._write(host, line)

    # -- loop ------------------------------------------------------------------
    def serve_forever(self) -> None:
        """Serve until :meth:`stop` is called."""
        reduce_timer_slack()
        # steps up to 5 ms cover any command rate of 200 Hz and more
        self.rig.plant.prepare(int(round(0.005 / self.rig.plant.quantum_s)))
        gc.collect()
        gc.freeze()  # what exists now is never scanned again: shorter collections
        self._t0 = self._clock()
        self._last_s = self._now()
        while not self._stop:
            self.serve_once()
        for host in list(self._hosts.values()):
            host.close()
        self._selector.close()

    def serve_once(self, wait_s: float | None = None) -> None:
        """One pass of the serve loop: what is due by now, then the sources that are ready.

        Parameters
        ----------
        wait_s : float, optional
            The longest to wait for a source (s); by default none while a host is connected (polling), else
            until the rig's next deadline, at most 50 ms.
        """
        rig = self.rig
        now = self._now()
        if self._hosts and self._last_s is not None:
            # time not serving, less what the rig chose to sleep waiting for a frame (none while polling)
            self.worst_gap_s = max(self.worst_gap_s, now - self._last_s - self._asleep_s)
        self._last_s = now
        # a loop that was held up is a rig that was: one heartbeat on resuming, not a burst of the missed ones
        rig.firmware.skip_missed_heartbeats(now)
        self._deliver_due(now)
        self._from_rig(rig.advance_to(now), now)
        if wait_s is None:
            if self._hosts and self.poll_while_connected:
                wait_s = 0.0  # poll: a sleeping process on a VM can wake milliseconds late
            else:
                wait_s = min(_MAX_WAIT_S, max(0.0, self._next_due_s() - self._now()))
        if wait_s > 0:  # a chosen sleep (not while polling): what it took is not a gap in serving
            asleep_from = self._now()
            ready = self._selector.select(timeout=wait_s)
            self._asleep_s = min(self._now() - asleep_from, wait_s)
        else:
            ready, self._asleep_s = self._selector.select(timeout=0), 0.0
        for key, events in ready:
            kind, obj = key.data
            if kind == "listen":
                self._accept(obj)
                continue
            if events & selectors.EVENT_WRITE:
                self._flush(obj)
            if events & selectors.EVENT_READ and obj.fd in self._hosts:
                self._read(obj)


def running_realtime() -> bool:
    """True when this process runs under a real-time scheduling policy (SCHED_FIFO or SCHED_RR)."""
    import os

    try:
        return os.sched_getscheduler(0) in (os.SCHED_FIFO, os.SCHED_RR)
    except (AttributeError, OSError):
        return False
