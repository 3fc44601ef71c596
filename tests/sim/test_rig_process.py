"""The rig as its own process, in real time, over slcan on loopback TCP.

The client in the first test is written against nothing but the DBC (read
with cantools) and firmware_proto/PROTOCOL.md: its CRC is computed here, not imported.
Real-time tests assert behaviour, not speed: time limits are generous
bounds on what must happen, and measured delays are printed.
"""

from __future__ import annotations

import gc
import os
import re
import select
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Iterator

import cantools
import pytest

from firmware_proto import dbc_path

pytestmark = pytest.mark.realtime


def cpu_steal_s() -> float:
    """CPU time the hypervisor took from this VM, all cores (Linux /proc/stat)."""
    try:
        with open("/proc/stat") as stat:
            fields = stat.readline().split()
        return int(fields[8]) / os.sysconf("SC_CLK_TCK")
    except (OSError, IndexError, ValueError):
        return 0.0


def crc8_j1850(data: bytes) -> int:
    crc = 0xFF
    for byte in data:
        crc ^= byte
        for _ in range(8):
            crc = ((crc << 1) ^ 0x1D) & 0xFF if crc & 0x80 else (crc << 1) & 0xFF
    return crc ^ 0xFF


@pytest.fixture()
def rig_process() -> Iterator[tuple[subprocess.Popen, int]]:
    proc = subprocess.Popen(
        [sys.executable, "-m", "edc_bench", "rig", "--listen", "127.0.0.1:0", "--seed", "7"],
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
    )
    assert proc.stdout is not None
    line = proc.stdout.readline()
    match = re.search(r"socket://127\.0\.0\.1:(\d+)", line)
    assert match, line
    try:
        yield proc, int(match.group(1))
    finally:
        proc.send_signal(signal.SIGTERM)
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()


class DbcClient:
    """A minimal slcan host: raw TCP, cantools and the ICD text only."""

    def __init__(self, port: int) -> None:
        self.db = cantools.database.load_file(str(dbc_path()))
        self.sock = socket.create_connection(("127.0.0.1", port))
        self.sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self.buffer = b""
        self.sock.sendall(b"C\rS6\rO\r")

    def send(self, name: str, **signals: float) -> None:
        message = self.db.get_message_by_name(name)
        data = bytearray(message.encode({"CRC": 0, **signals}))
        data[0] = crc8_j1850(bytes([message.frame_id & 0xFF]) + bytes(data[1:]))
        self.send_raw(message.frame_id, bytes(data))

    def send_raw(self, can_id: int, data: bytes) -> None:
        self.sock.sendall(f"t{can_id:03X}{len(data)}{data.hex().upper()}\r".encode())

    def frames(self, timeout_s: float) -> Iterator[tuple[float, str, dict]]:
        """Decoded frames (arrival time, name, signals) until timeout_s passes."""
        end = time.perf_counter() + timeout_s
        while True:
            while b"\r" in self.buffer:
                line, self.buffer = self.buffer.split(b"\r", 1)
                text = line.decode()
                if text.startswith("t"):
                    can_id, dlc = int(text[1:4], 16), int(text[4])
                    data = bytes.fromhex(text[5:5 + 2 * dlc])
                    message = self.db.get_message_by_frame_id(can_id)
                    yield time.perf_counter(), message.name, message.decode(data, decode_choices=False)
            remaining = end - time.perf_counter()
            if remaining <= 0:
                return
            ready, _, _ = select.select([self.sock], [], [], remaining)
            if ready:
                chunk = self.sock.recv(4096)
                if not chunk:
                    return
                self.buffer += chunk

    def wait_for(self, name: str, timeout_s: float, **match: float) -> tuple[float, dict]:
        for arrival, got, signals in self.frames(timeout_s):
            if got == name and all(signals[k] == v for k, v in match.items()):
                return arrival, signals
        raise AssertionError(f"no {name} {match} within {timeout_s} s")

    def close(self) -> None:
        self.sock.close()


@pytest.fixture()
def no_gc() -> Iterator[None]:
    """Keep the garbage collector out of a real-time exchange, as the bench loop does."""
    gc.collect()
    gc.disable()
    try:
        yield
    finally:
        gc.enable()


def test_client_from_dbc_only_drives_the_rig(rig_process, no_gc) -> None:
    _, port = rig_process
    client = DbcClient(port)
    try:
        client.wait_for("RIG_HEARTBEAT", 5.0, State=1)  # READY

        # RUN commands at about 1 kHz: echoed counters, rack rising to the hold position.
        # This VM can stall a process for longer than the 20 ms watchdog (CPU steal);
        # the rig then trips as it must. Re-arm and retry, and say so.
        counter = 0
        disturbances = []
        for attempt in range(3):
            # SAFE (answered, rig READY) until the rack is back at its rest stop: after a disturbed attempt that did
            # not trip, the rack still hung at the hold position (a CI run on a loaded machine read 10.28 mm first)
            rest_by = time.perf_counter() + 3.0
            while True:
                counter += 1
                client.send("BENCH_CMD", Counter=counter % 256, Mode=0, DriveVoltage=0.0, RackReference=0.0)
                _, safe = client.wait_for("RIG_FEEDBACK", 1.0, Counter=counter % 256)
                if safe["RackPosition"] < 1.0 or time.perf_counter() > rest_by:
                    break
                time.sleep(0.02)
            replies = []
            max_gap_s, max_reply_s, previous = 0.0, 0.0, time.perf_counter()
            steal_before_s = cpu_steal_s()
            for _ in range(600):
                counter += 1
                sent = time.perf_counter()
                max_gap_s, previous = max(max_gap_s, sent - previous), sent
                client.send("BENCH_CMD", Counter=counter % 256, Mode=1, DriveVoltage=2.8, RackReference=10.0)
                _, fb = client.wait_for("RIG_FEEDBACK", 1.0)
                assert fb["Counter"] == counter % 256
                replies.append(fb)
                # the rig's watchdog runs from when it took the command, between our send and its reply reaching us:
                # timed from the reply, a reply that reached this process late made the watchdog look early (16 ms)
                last_valid_command = sent
                max_reply_s = max(max_reply_s, time.perf_counter() - sent)
                if fb["WatchdogTripped"]:
                    break
                time.sleep(0.0005)
            steal_s = cpu_steal_s() - steal_before_s
            undisturbed = steal_s < 0.05 and max_gap_s < 0.015 and max_reply_s < 0.015
            # a rig process held up for tens of ms integrates its plant over the hold at once: the rack "jumps"
            # (10.4 mm at the fourth reply, seen while two test suites and a CPU load shared 2 cores)
            jumped = len(replies) > 3 and replies[3]["RackPosition"] >= 5.0
            if not replies[-1]["WatchdogTripped"] and (undisturbed or not jumped):
                break
            what = "watchdog tripped" if replies[-1]["WatchdogTripped"] else "rack jumped at the fourth reply"
            message = (f"attempt {attempt + 1}: {what} after {len(replies)} commands; longest gap between "
                       f"sends {max_gap_s * 1e3:.1f} ms, longest reply {max_reply_s * 1e3:.1f} ms, CPU steal "
                       f"meanwhile {steal_s * 1e3:.0f} ms")
            print(message)
            # a 20 ms watchdog cannot hold when this machine stalls the processes for longer
            if undisturbed:
                pytest.fail(f"watchdog tripped on an undisturbed machine: {message}")
            disturbances.append(message)
        else:
            pytest.skip("every attempt was disturbed by this machine: " + "; ".join(disturbances))
        assert all(r["AmpEnabled"] == 1 and r["WatchdogTripped"] == 0 for r in replies)
        positions = [r["RackPosition"] for r in replies]
        assert positions[0] < 1.0  # at the rest stop before the first drive
        assert positions[3] < 5.0  # the plant's dynamics: no instant jump
        assert 8.5 < positions[-1] < 11.5  # 2.8 V holds about mid-stroke

        # bad CRC and a repeated counter: no reply
        steal_before_trip_s = cpu_steal_s()
        message = client.db.get_message_by_name("BENCH_CMD")
        good = bytearray(message.encode({"CRC": 0, "Counter": (counter + 1) % 256, "Mode": 1, "DriveVoltage": 2.8,
                                         "RackReference": 10.0}))
        good[0] = crc8_j1850(bytes([0x20]) + bytes(good[1:])) ^ 0x55
        client.send_raw(0x120, bytes(good))
        client.send("BENCH_CMD", Counter=counter % 256, Mode=1, DriveVoltage=2.8, RackReference=10.0)
        assert not [f for f in client.frames(0.015) if f[1] == "RIG_FEEDBACK"]

        # no valid command since the last RUN: the watchdog trips, announced by a FAULT heartbeat
        tripped_at, beat = client.wait_for("RIG_HEARTBEAT", 2.0, State=3)
        delay_ms = (tripped_at - last_valid_command) * 1e3
        print(f"watchdog FAULT seen {delay_ms:.1f} ms after the last valid command (ICD: 20 ms)")
        assert beat["FaultCode"] == 1  # WATCHDOG
        # the rig's own 20 ms is exact in simulated time (test_firmware); here allow for scheduling. Early is a bug
        # whatever the machine did; late is the machine's doing when it was oversubscribed or its CPU stolen (130 ms
        # seen on CI's 3.13 suite: two workers and a CPU load on two cores), which skips at the end, saying so
        assert delay_ms > 19.0
        late = ""
        if delay_ms >= 120.0:
            load = os.getloadavg()[0]
            steal_s = cpu_steal_s() - steal_before_trip_s
            cores = os.cpu_count() or 1
            late = (f"watchdog FAULT seen {delay_ms:.1f} ms after the last valid command (bound 120 ms), with a load "
                    f"of {load:.1f} on {cores} cores and {steal_s * 1e3:.0f} ms CPU steal")
            if load <= cores and steal_s < 0.05:
                pytest.fail(f"on an undisturbed machine: {late}")
        # RUN now is answered with WatchdogTripped and the amplifier off; the coil current
        # (tau = L/R, about 1.4 ms) dies away: 0 V is applied
        currents = []
        for _ in range(10):
            counter += 1
            client.send("BENCH_CMD", Counter=counter % 256, Mode=1, DriveVoltage=2.8, RackReference=10.0)
            _, fb = client.wait_for("RIG_FEEDBACK", 1.0, Counter=counter % 256)
            assert fb["WatchdogTripped"] == 1 and fb["AmpEnabled"] == 0
            currents.append(fb["CoilCurrent"])
            time.sleep(0.002)
        assert abs(currents[-1]) < 0.1, currents

        # SAFE re-arms; RUN drives again
        client.send("BENCH_CMD", Counter=(counter + 1) % 256, Mode=0, DriveVoltage=0.0, RackReference=0.0)
        client.wait_for("RIG_HEARTBEAT", 1.0, State=1)
        client.send("BENCH_CMD", Counter=(counter + 2) % 256, Mode=1, DriveVoltage=2.8, RackReference=10.0)
        _, fb = client.wait_for("RIG_FEEDBACK", 1.0)
        assert fb["AmpEnabled"] == 1 and fb["WatchdogTripped"] == 0
        if late:  # everything else held: only the watchdog's timing went unjudged
            pytest.skip(f"the machine got in the way: {late}")
    finally:
        client.close()


def test_python_can_slcan_interface_drives_the_rig(rig_process, no_gc) -> None:
    import can

    from edc_bench.protocol import BENCH_CMD_ID, RIG_FEEDBACK_ID, RIG_HEARTBEAT_ID, Mode, RigState, default_icd

    _, port = rig_process
    icd = default_icd()
    bus = can.Bus(interface="slcan", channel=f"socket://127.0.0.1:{port}", bitrate=500_000, sleep_after_open=0)
    try:
        deadline = time.perf_counter() + 5.0
        state = None
        while state is not RigState.READY and time.perf_counter() < deadline:
            msg = bus.recv(0.2)
            if msg is not None and msg.arbitration_id == RIG_HEARTBEAT_ID:
                state = icd.parse_heartbeat(msg.data).state
        assert state is RigState.READY
        for k in range(1, 101):
            bus.send(can.Message(arbitration_id=BENCH_CMD_ID, is_extended_id=False,
                                 data=icd.make_bench_cmd(k, Mode.RUN, 2.0, 10.0)))
            while True:
                msg = bus.recv(1.0)
                assert msg is not None, "no RIG_FEEDBACK"
                if msg.arbitration_id == RIG_FEEDBACK_ID:
                    assert icd.parse_rig_feedback(msg.data).counter == k
                    break
        bus.send(can.Message(arbitration_id=BENCH_CMD_ID, is_extended_id=False,
                             data=icd.make_bench_cmd(101, Mode.SAFE, 0.0, 0.0)))
    finally:
        bus.shutdown()


@pytest.mark.skipif(not hasattr(os, "openpty"), reason="needs pseudo-terminals")
def test_pty_mode_serves_slcan() -> None:
    import serial

    proc = subprocess.Popen([sys.executable, "-m", "edc_bench", "rig", "--pty"], stdout=subprocess.PIPE, text=True)
    try:
        assert proc.stdout is not None
        match = re.search(r"serving slcan at (\S+)", proc.stdout.readline())
        assert match
        port = serial.Serial(match.group(1), timeout=2.0)
        port.write(b"O\r")
        data = b""
        deadline = time.perf_counter() + 3.0
        while b"t720" not in data and time.perf_counter() < deadline:
            data += port.read(port.in_waiting or 1)
        assert b"t720" in data  # heartbeats arrive over the pty
        port.close()
    finally:
        proc.send_signal(signal.SIGTERM)
        proc.wait(timeout=10)
