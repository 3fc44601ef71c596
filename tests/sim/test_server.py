"""The rig server under hostile hosts, one pass of its loop at a time, on a fake clock.

Hosts are socketpairs handed to the server; the clock is the test's, so
nothing here depends on how fast this machine runs. A loop that blocks on a
host is caught by an alarm (``no_hang``) instead of hanging the suite.
"""

from __future__ import annotations

import signal
import socket
from collections.abc import Iterator

import numpy as np
import pytest

from edc_bench.config import Variant
from edc_bench.physics.valve import parse_valve_spec
from edc_bench.protocol import BENCH_CMD_ID, Icd, Mode, RigState
from edc_bench.protocol.slcan import parse_frame_line
from edc_bench.sim.rig import SimulatedRig
from edc_bench.sim.server import HostStats, SlcanRigServer

BEL = b"\a"
PERIOD_S = 1e-3


class FakeClock:
    """The server's clock, moved by the test."""

    def __init__(self) -> None:
        self.now_s = 0.0

    def __call__(self) -> float:
        return self.now_s


class Host:
    """The host's end of a socketpair whose other end the server serves."""

    def __init__(self, server: SlcanRigServer, name: str, *, small_buffers: bool = False) -> None:
        self.sock, served = socket.socketpair()
        if small_buffers:  # little room in the kernel: a host that does not read fills it at once
            served.setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, 4096)
            self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
        server.add_host(served, name)
        self.sock.setblocking(False)
        self._pending = b""

    def send(self, data: bytes) -> None:
        self.sock.sendall(data)

    def send_frame(self, can_id: int, data: bytes) -> None:
        self.send(f"t{can_id:03X}{len(data)}{data.hex().upper()}\r".encode())

    def read(self) -> list[bytes]:
        """Everything the server sent since the last read: lines without their CR, and BEL as its own item."""
        while True:
            try:
                chunk = self.sock.recv(65536)
            except BlockingIOError:
                break
            if not chunk:
                break
            self._pending += chunk
        items: list[bytes] = []
        line = b""
        for byte in self._pending:
            if byte == BEL[0]:
                items.append(BEL)
            elif byte == ord("\r"):
                items.append(line)
                line = b""
            else:
                line += bytes([byte])
        self._pending = line
        return items


def frames_of(items: list[bytes], prefix: bytes) -> list[bytes]:
    """Payloads of the frame lines starting with ``prefix`` (``b"t121"``: standard id 0x121)."""
    return [bytes.fromhex(item[len(prefix) + 1:].decode()) for item in items if item.startswith(prefix)]


@pytest.fixture()
def no_hang() -> Iterator[None]:
    """Turn a serve loop blocked on a host into a failure instead of a hung suite."""

    def blocked(*_: object) -> None:
        pytest.fail("the serve loop blocked on a host for 10 s")  # not an OSError: the loop must not swallow it

    previous = signal.signal(signal.SIGALRM, blocked)
    signal.setitimer(signal.ITIMER_REAL, 10.0)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0.0)
        signal.signal(signal.SIGALRM, previous)


@pytest.fixture()
def served(variant: Variant, no_hang: None) -> tuple[SlcanRigServer, FakeClock, list[str]]:
    clock, logs = FakeClock(), []
    rig = SimulatedRig(variant, parse_valve_spec("new", variant), seed=0)
    return SlcanRigServer(rig, clock_s=clock, log=logs.append, host_queue_bytes=4096), clock, logs


def run_until(server: SlcanRigServer, clock: FakeClock, t_s: float) -> None:
    """Serve pass by pass, one period apart, until ``t_s``."""
    while clock.now_s < t_s - 1e-9:
        clock.now_s += PERIOD_S
        server.serve_once(0.0)


def open_hosts(server: SlcanRigServer, clock: FakeClock, *hosts: Host) -> None:
    """Open every host's channel and serve until the rig is READY; what they got meanwhile is read."""
    for host in hosts:
        host.send(b"O\r")
    run_until(server, clock, 0.3)
    assert server.rig.firmware.state is RigState.READY
    for host in hosts:
        host.read()


def stats(server: SlcanRigServer, name: str) -> HostStats:
    return next(s for s in server.host_stats() if s.name == name)


# -- #13 item 5: a stalled host ----------------------------------------------------------------------------------------


def test_a_host_that_never_reads_holds_up_neither_the_rig_nor_the_others(served, icd: Icd) -> None:
    server, clock, logs = served
    stalled, bench = Host(server, "stalled", small_buffers=True), Host(server, "bench")
    open_hosts(server, clock, stalled, bench)
    counters, beat_times_s = [], []
    for k in range(1, 1001):  # 1 s at 1 kHz: SAFE commands are answered and keep the rig READY
        bench.send_frame(BENCH_CMD_ID, icd.make_bench_cmd(k % 256, Mode.SAFE, 0.0, 0.0))
        clock.now_s += PERIOD_S
        server.serve_once(0.0)
        items = bench.read()
        counters += [icd.parse_rig_feedback(d).counter for d in frames_of(items, b"t121")]
        beat_times_s += [clock.now_s] * len(frames_of(items, b"t720"))
    assert counters == [k % 256 for k in range(1, 1001)]  # every command answered in its own pass
    assert len(beat_times_s) >= 9 and np.allclose(np.diff(beat_times_s), 0.1, atol=1.5e-3)  # heartbeats on time
    assert stats(server, "stalled").dropped_lines > 0
    assert [line for line in logs if "stalled" in line and "connected" not in line] == [
        "host stalled: not reading; output queue full at 4096 bytes, dropping its frames as an adapter overflows"]
    # what the stalled host gets when it reads again is whole lines, then the overrun in its status flags
    items = []
    for _ in range(100):
        items += stalled.read()
        clock.now_s += PERIOD_S
        server.serve_once(0.0)
    assert all(item in (b"", b"z") or parse_frame_line(item) is not None for item in items)
    stalled.send(b"F\r")
    server.serve_once(0.0)
    assert b"F08" in stalled.read()
    assert not [line for line in logs if "disconnected" in line]


def test_a_stalled_rig_sends_one_heartbeat_on_resuming_and_keeps_its_grid(served) -> None:
    server, clock, _ = served
    monitor = Host(server, "monitor")
    open_hosts(server, clock, monitor)
    clock.now_s = 1.05  # the serve loop was held up from 0.3 s to 1.05 s: beats due at 0.4 ... 1.0 missed
    server.serve_once(0.0)
    assert len(frames_of(monitor.read(), b"t720")) == 1
    assert server.rig.firmware.next_deadline_s() == pytest.approx(1.1)
    run_until(server, clock, 1.25)
    assert len(frames_of(monitor.read(), b"t720")) == 2  # 1.1 s and 1.2 s


# -- #13 item 7: malformed lines, remote frames ------------------------------------------------------------------------


def test_malformed_lines_are_answered_bel_counted_and_never_forwarded(served, icd: Icd) -> None:
    server, clock, _ = served
    sender, monitor = Host(server, "sender"), Host(server, "monitor")
    open_hosts(server, clock, sender, monitor)
    payload = icd.make_bench_cmd(1, Mode.RUN, 3.0, 10.0).hex().upper().encode()
    bad = [b"t+1208" + payload, b"t-1208" + payload, b"t_1208" + payload, b"t1208" + payload + b"00",
           b"t9208" + payload, b"T200001208" + payload, b"t1209" + payload + b"00", b"r1208" + payload[:2]]
    sender.send(b"".join(line + b"\r" for line in bad))
    server.serve_once(0.0)
    assert sender.read() == [BEL] * len(bad)
    assert not [item for item in monitor.read() if item != b"" and not item.startswith(b"t720")]
    assert stats(server, "sender").malformed_lines == len(bad)
    assert server.rig.firmware.counters.accepted == 0 and server.rig.plant.drive_v == 0.0


def test_remote_frames_are_forwarded_as_remote_frames(served) -> None:
    server, clock, _ = served
    sender, monitor = Host(server, "sender"), Host(server, "monitor")
    open_hosts(server, clock, sender, monitor)
    sender.send(b"r1234\rR000001230\r")
    server.serve_once(0.0)
    assert sender.read() == [b"z", b"Z"]
    assert [item for item in monitor.read() if not item.startswith(b"t720")] == [b"r1234", b"R000001230"]


# -- #13 item 8: who owns the rig --------------------------------------------------------------------------------------


def test_a_second_host_cannot_command_the_rig_while_another_runs_a_test(served, icd: Icd) -> None:
    server, clock, logs = served
    owner, intruder, monitor = Host(server, "owner"), Host(server, "intruder"), Host(server, "monitor")
    open_hosts(server, clock, owner, intruder, monitor)
    counters, intruder_items, seen = [], [], []
    for k in range(1, 201):
        owner.send_frame(BENCH_CMD_ID, icd.make_bench_cmd(k % 256, Mode.RUN, 2.0, 10.0))
        if k in (50, 100, 150):  # valid RUN commands with a correct CRC and the owner's next counter
            intruder.send_frame(BENCH_CMD_ID, icd.make_bench_cmd((k + 1) % 256, Mode.RUN, 20.0, 10.0))
            intruder.send_frame(0x7DF, b"\x02\x01\x00")  # any other frame still goes on the bus
        clock.now_s += PERIOD_S
        server.serve_once(0.0)
        assert server.rig.plant.drive_v == 2.0
        counters += [icd.parse_rig_feedback(d).counter for d in frames_of(owner.read(), b"t121")]
        intruder_items += intruder.read()
        seen += monitor.read()
    assert counters == list(range(1, 201))  # the owner's test undisturbed: no reply missing, none extra
    assert [item for item in intruder_items if not item.startswith((b"t720", b"t121", b"t120"))] == [BEL, b"z"] * 3
    assert len(frames_of(seen, b"t120")) == 200 and len(frames_of(seen, b"t7DF")) == 3  # the intruder's not forwarded
    assert all(icd.parse_bench_cmd(d).drive_v == 2.0 for d in frames_of(seen, b"t120"))
    assert [line for line in logs if "refused" in line] == [
        "host intruder: BENCH_CMD refused, the rig is owned by owner"]  # once per host
    assert stats(server, "intruder").refused_bench_cmds == 3


def test_the_rig_passes_on_after_a_finished_test_or_a_disconnect(served, icd: Icd) -> None:
    server, clock, _ = served
    first, second = Host(server, "first"), Host(server, "second")
    open_hosts(server, clock, first, second)

    def command(host: Host, counter: int, mode: Mode) -> list[bytes]:
        """What the host gets for its command: z and RIG_FEEDBACK, or BEL."""
        host.read()
        host.send_frame(BENCH_CMD_ID, icd.make_bench_cmd(counter, mode, 2.0, 10.0))
        clock.now_s += PERIOD_S
        server.serve_once(0.0)
        return [item for item in host.read() if not item.startswith((b"t720", b"t120"))]

    assert len(command(first, 1, Mode.RUN)) == 2  # z, RIG_FEEDBACK: first owns the rig
    run_until(server, clock, clock.now_s + 1.5)  # the owner went quiet while RUNNING: the watchdog trips
    assert server.rig.firmware.state is RigState.FAULT
    assert command(second, 10, Mode.SAFE) == [BEL]  # not READY: still the owner's
    assert len(command(first, 2, Mode.SAFE)) == 2  # the owner's test ends: READY
    run_until(server, clock, clock.now_s + 0.99)
    assert command(second, 10, Mode.SAFE) == [BEL]  # READY, but not yet for 1 s
    run_until(server, clock, clock.now_s + 0.01)
    assert len(command(second, 11, Mode.SAFE)) == 2  # 1 s in READY after SAFE: second owns it now
    assert command(first, 3, Mode.SAFE) == [BEL]
    second.sock.close()  # its owner gone, the rig is free at once
    server.serve_once(0.0)
    assert len(command(first, 4, Mode.SAFE)) == 2


def test_a_command_the_rig_refuses_wins_no_ownership(served, icd: Icd) -> None:
    """A host sending BENCH_CMDs the rig refuses (here a bad CRC) cannot hold the rig against a real bench."""
    server, clock, _ = served
    junk, bench = Host(server, "junk"), Host(server, "bench")
    open_hosts(server, clock, junk, bench)
    bad_crc = bytearray(icd.make_bench_cmd(1, Mode.RUN, 2.0, 10.0))
    bad_crc[-1] ^= 0xFF
    junk.send_frame(BENCH_CMD_ID, bytes(bad_crc))
    clock.now_s += PERIOD_S
    server.serve_once(0.0)
    bench.read()
    bench.send_frame(BENCH_CMD_ID, icd.make_bench_cmd(1, Mode.RUN, 2.0, 10.0))
    clock.now_s += PERIOD_S
    server.serve_once(0.0)
    replies = [item for item in bench.read() if item.startswith(b"t121")]
    assert len(replies) == 1 and server.rig.firmware.state is RigState.RUNNING  # the bench owns the rig
    assert stats(server, "junk").refused_bench_cmds == 0  # delivered and refused by the rig, not by the server


def test_a_rig_that_sleeps_between_frames_delivers_what_its_adapter_holds_on_time(variant: Variant, icd: Icd,
                                                                                  no_hang: None) -> None:
    """Under SCHED_FIFO the server sleeps instead of polling; it slept until the firmware's next deadline past the
    replies a USB adapter held, and each reply went out only when the next command woke it: rig-check failed 7
    checks (replies paired with the wrong commands)."""
    import select

    from edc_bench.sim.adapter import parse_adapter

    clock, logs = FakeClock(), []
    rig = SimulatedRig(variant, parse_valve_spec("new", variant), seed=0)
    server = SlcanRigServer(rig, clock_s=clock, log=logs.append, host_queue_bytes=4096,
                            adapter=parse_adapter("usb-fs"))
    server.poll_while_connected = False  # as under a real-time policy
    real_select = server._selector.select
    bench = Host(server, "bench")
    open_hosts(server, clock, bench)
    bench.read()
    sent_s, latencies_s = 0.0, []

    def sleeping_select(timeout: float | None = None) -> list:
        if select.select([bench.sock], [], [], 0)[0] and len(latencies_s) < k:  # the reply is out: when
            latencies_s.append(clock.now_s - sent_s)
        ready = real_select(timeout=0)
        if not ready:  # nothing came: the whole sleep, in the test's time
            clock.now_s += timeout or 0.0
        return ready

    server._selector.select = sleeping_select
    for k in range(1, 21):
        sent_s = clock.now_s
        bench.send_frame(BENCH_CMD_ID, icd.make_bench_cmd(k, Mode.RUN, 1.0, 10.0))
        replies: list[bytes] = []
        while not replies and clock.now_s < sent_s + 0.2:
            server.serve_once()
            replies = frames_of(bench.read(), b"t121")
        assert [icd.parse_rig_feedback(d).counter for d in replies] == [k]  # its own reply, before the next command
        clock.now_s += 0.005
    assert len(latencies_s) == 20 and max(latencies_s) < 0.01, latencies_s  # usb-fs: a few ms, not the 50 ms sleep
