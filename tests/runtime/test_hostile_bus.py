"""A hostile or broken bus costs neither the record nor the rig's safety (#13).

The bench runs its real slcan path (python-can's slcan bus through
``BufferedSlcanBus``, pyserial's ``socket://``, a loopback TCP connection)
against the simulated rig in simulated time (``SlcanSocketRig``), which
misbehaves at ``FAULT_AT_S``: drops the connection, sends bytes that are not
ASCII, extended frames, damaged lines, another host's BENCH_CMD. Each test
checks the record on disk is complete and, where the test must end, that
SAFE followed the detection within 20 ms (or the rig's watchdog acted where
the bus is gone).
"""

from __future__ import annotations

import errno
import json
import time
from collections.abc import Iterator
from pathlib import Path

import can
import pytest
from helpers import check_safe_and_complete

from edc_bench.bench import BenchResult, BenchOptions, run_bench_test
from edc_bench.config import load_variant, with_changes
from edc_bench.engine.outcome import AbortKind
from edc_bench.engine.trace import FRAME_EXTENDED, FRAME_REMOTE, FRAME_TRUNCATED, CanFrameLog
from edc_bench.physics.valve import parse_valve_spec
from edc_bench.protocol import BENCH_CMD_ID, RIG_FEEDBACK_ID, Mode, default_icd
from edc_bench.protocol.slcan import SlcanFrame, format_frame_line
from edc_bench.records.record import write_record
from edc_bench.runtime.bus import BufferedSlcanBus, ClosingBus, close_quietly, open_bus
from edc_bench.runtime.clock import SimulatedClock
from edc_bench.runtime.loop import BenchLoop
from edc_bench.sim.rig import SimulatedRig
from edc_bench.testing.slcan_rig import SlcanSocketRig
from edc_bench.verdict.verdicts import Verdict

FAULT_AT_S = 2.5
SHORT_S = 8.0  # tests that must run to their end (too short to converge: they end INVALID "not converged")


def _variant(duration_s: float = 30.0):
    return with_changes(load_variant(), {"excitation": {"duration_s": duration_s}}, "test")


def run_over_slcan(link_action, duration_s: float = 30.0, valve: str = "worn") -> tuple[BenchResult, SimulatedRig,
                                                                                          ClosingBus]:
    """One test over a real slcan socket; ``link_action(link)`` schedules the misbehaviour."""
    variant = _variant(duration_s)
    rig = SimulatedRig(variant, parse_valve_spec(valve, variant), 1)
    link = SlcanSocketRig(rig)
    session = ClosingBus(open_bus({"interface": "slcan", "channel": link.channel}, default_icd().bitrate))
    with session as bus:
        link.accept()
        link_action(link)
        clock = SimulatedClock(link)
        result = run_bench_test(bus, clock, variant, BenchOptions(check_gains=False))
    rig.advance_to(clock.now_s() + 0.025)  # 25 ms after the bench's last word: the watchdog has acted
    return result, rig, session


def _record(result: BenchResult, tmp_path: Path) -> tuple[dict, Path]:
    folder = write_record(result, tmp_path, figure=False)
    return json.loads((folder / "record.json").read_text()), folder


def _safe_within_20_ms(result: BenchResult) -> float:
    """Seconds from the abort's detection to the first SAFE the bench sent after it."""
    outcome, frames, icd = result.outcome, result.frames, default_icd()
    detected = outcome.ticks_start_s + outcome.abort_time_s
    for k in range(frames.count):
        if (not frames.rx[k] and frames.can_id[k] == BENCH_CMD_ID and frames.t_s[k] >= detected
                and icd.parse_bench_cmd(bytes(frames.data[k])).mode == Mode.SAFE):
            return float(frames.t_s[k] - detected)
    raise AssertionError("no SAFE command after the abort")


def ran_to_the_end(result: BenchResult) -> bool:
    """Not aborted, every reply in time, SAFE confirmed at the end."""
    outcome = result.outcome
    return (outcome.abort_reason is None and outcome.missed_replies == 0 and outcome.safe_confirmed
            and outcome.ticks_run == outcome.ticks_planned)


def test_a_clean_slcan_run_goes_to_its_end() -> None:
    """The harness itself: no misbehaviour, every reply matched."""
    result, rig, session = run_over_slcan(lambda link: None, SHORT_S)
    assert ran_to_the_end(result) and result.outcome.bus_bad_lines == 0
    assert session.close_error is None


def test_tcp_disconnect_mid_test_keeps_the_record_and_the_rig_is_safe(tmp_path: Path) -> None:
    """Defect 1: leaving the bus context after the connection died raised, and the record was never written."""
    result, rig, session = run_over_slcan(lambda link: link.at(FAULT_AT_S, link.disconnect))
    assert result.outcome.abort_reason.startswith("bus error: CanOperationError"), result.outcome.abort_reason
    assert session.close_error is not None  # closing the dead connection failed, and was only noted
    check_safe_and_complete(result, rig, tmp_path)  # the rig's watchdog put it at 0 V: the bus is gone
    assert result.outcome.ticks_run == pytest.approx(FAULT_AT_S * 1000 - 200, abs=60)


def test_a_byte_that_is_not_ascii_is_skipped_not_fatal(tmp_path: Path) -> None:
    """Defect 2: one non-UTF-8 byte ended the test and then the safe stop; now the line is counted and skipped."""
    junk = [b"\xff\xfe\r", b"t1\xff18\x00\x01\r", b"\x80" * 100]

    def act(link: SlcanSocketRig) -> None:
        for n, data in enumerate(junk):
            link.at(FAULT_AT_S + 0.1 * n, lambda data=data: link.write(data))

    result, _, _ = run_over_slcan(act, SHORT_S)
    assert ran_to_the_end(result) and result.outcome.bus_bad_lines == 3
    doc, _ = _record(result, tmp_path)
    assert doc["loop"]["bus_bad_lines"] == 3 and "\\xff" in doc["loop"]["bus_bad_line_samples"][0]


def test_extended_ids_and_damaged_lines_are_logged_or_counted_never_taken_for_replies(tmp_path: Path) -> None:
    """Defect 3: a 29-bit id overflowed the frame log, a bad hex digit raised in python-can's parser."""
    icd = default_icd()
    # a perfect RIG_FEEDBACK payload, but in an extended frame: another protocol's frame, never a reply
    forged = icd.make_rig_feedback(0, amp_enabled=True, watchdog_tripped=False, over_current=False, lvdt_fault=False,
                                   travel_limit=False, position_mm=9.0, current_a=0.5)
    damaged = [b"tZZZ8\r", b"t12\r", b"t1218" + b"00" * 8 + b"FF\r", b"t-208" + b"00" * 8 + b"\r",
               b"t_12800\r", b"t8001" + b"00\r", b"T200000001" + b"00\r"]

    def act(link: SlcanSocketRig) -> None:
        link.at(FAULT_AT_S, lambda: link.write_frame(0x1ABCDEF0, b"\x01\x02\x03", extended=True))
        link.at(FAULT_AT_S + 0.05, lambda: link.write_frame(RIG_FEEDBACK_ID, forged, extended=True))
        link.at(FAULT_AT_S + 0.1, lambda: [link.write(line) for line in damaged])
        # a BENCH_CMD with a payload the rig would refuse (bad CRC): damage, not a second host driving the rig
        link.at(FAULT_AT_S + 0.2, lambda: link.write_frame(BENCH_CMD_ID, bytes(8)))

    result, _, _ = run_over_slcan(act, SHORT_S)
    outcome = result.outcome
    assert ran_to_the_end(result)
    assert outcome.bus_bad_lines == len(damaged)
    assert outcome.other_frames == 2
    frames = result.frames
    extended = [k for k in range(frames.count) if frames.flags[k] & FRAME_EXTENDED]
    assert [int(frames.can_id[k]) for k in extended] == [0x1ABCDEF0, RIG_FEEDBACK_ID]
    doc, folder = _record(result, tmp_path)
    logged = [m for m in can.LogReader(str(folder / "can.log")) if m.is_extended_id]
    assert [(m.arbitration_id, bytes(m.data)) for m in logged] == [(0x1ABCDEF0, b"\x01\x02\x03"),
                                                                  (RIG_FEEDBACK_ID, bytes(forged))]
    assert doc["loop"]["other_frames"] == 2
    # the replay from can.log leaves the extended frames aside as the loop did: the same result to the last bit
    from edc_bench.replay import replay_record

    report = replay_record(folder)
    assert report.reproduced, report.differences


def test_another_hosts_command_ends_the_test_with_safe(tmp_path: Path) -> None:
    """Defect 8, the bench's side: a second host sending BENCH_CMD on the bus is detected; SAFE within 20 ms."""
    intruder = default_icd().make_bench_cmd(7, Mode.RUN, 3.0, 10.0)
    result, rig, _ = run_over_slcan(lambda link: link.at(FAULT_AT_S, lambda: link.write_frame(BENCH_CMD_ID,
                                                                                                intruder)))
    assert result.outcome.abort.kind is AbortKind.FOREIGN_COMMAND
    assert result.outcome.abort_reason.startswith("another host is sending BENCH_CMD on the bus")
    assert _safe_within_20_ms(result) <= 0.020
    assert result.outcome.safe_confirmed
    check_safe_and_complete(result, rig, tmp_path)


def test_another_hosts_test_is_never_broken_into(tmp_path: Path) -> None:
    """A rig another host is driving when this bench starts: no SAFE of ours, one clear reason."""
    intruder = default_icd().make_bench_cmd(7, Mode.RUN, 3.0, 10.0)
    result, _, _ = run_over_slcan(lambda link: link.at(0.05, lambda: link.write_frame(BENCH_CMD_ID, intruder)))
    assert result.outcome.abort.kind is AbortKind.FOREIGN_COMMAND
    assert result.outcome.abort_reason.startswith("another host is sending BENCH_CMD on the bus")
    sent = [k for k in range(result.frames.count) if not result.frames.rx[k]]
    assert sent == []  # the bench never sent a frame into the other host's test
    doc, _ = _record(result, tmp_path)
    assert doc["verdict"] == Verdict.INVALID and any("no SAFE sent" in e for e in doc["loop"]["events"])


def test_an_interface_echoing_our_own_commands_is_not_another_host() -> None:
    """Some interfaces deliver the bench's own frames back (receive_own_messages): not a second host."""

    class EchoBus(BufferedSlcanBus):
        def send(self, msg: can.Message, timeout: float | None = None) -> None:
            super().send(msg, timeout)
            self._echo.append(msg)

        def _recv_internal(self, timeout):
            if self._echo:
                return self._echo.pop(0), False
            return super()._recv_internal(timeout)

    variant = _variant(SHORT_S)
    rig = SimulatedRig(variant, parse_valve_spec("new", variant), 1)
    link = SlcanSocketRig(rig)
    EchoBus._echo = []
    with ClosingBus(EchoBus(link.channel, bitrate=500000, sleep_after_open=0)) as bus:
        link.accept()
        result = run_bench_test(bus, SimulatedClock(link), variant, BenchOptions(check_gains=False,
                                                                                classify=False))
    assert result.outcome.abort_reason is None, result.outcome.abort_reason


# -- defect 4: a full disk --------------------------------------------------------------------------------------


@pytest.fixture()
def disk_full_after(monkeypatch: pytest.MonkeyPatch) -> Iterator[list[int]]:
    """The CAN-log streamer's writes fail with ENOSPC once the test's clock passes FAULT_AT_S."""
    from edc_bench.records import stream

    calls = [0]
    original = stream.StreamingCanLog._flush_new

    def flush(self) -> None:
        if self.frames.count and self.frames.t_s[self.frames.count - 1] > FAULT_AT_S:
            calls[0] += 1
            raise OSError(errno.ENOSPC, "No space left on device")
        original(self)

    monkeypatch.setattr(stream.StreamingCanLog, "_flush_new", flush)
    yield calls


def test_a_full_disk_while_streaming_costs_neither_the_verdict_nor_the_log(tmp_path: Path, disk_full_after,
                                                                          simulated_bench) -> None:
    """Defect 4: ENOSPC in the CAN-log streamer escaped as a thread traceback and the result was lost."""
    variant = _variant(SHORT_S)
    bench, clock, _ = simulated_bench(variant, "worn", 1)
    folder = tmp_path / "rec"
    folder.mkdir()
    # the streamer writes every 0.1 s of wall-clock time, and once more at the end: past FAULT_AT_S either fails
    result = run_bench_test(bench, clock, variant,
                            BenchOptions(check_gains=False, stream_can_log=lambda _started: folder / "can.log"))
    assert disk_full_after[0] >= 1
    assert ran_to_the_end(result) and result.can_log_path is None
    assert any("can.log could not be streamed" in e and "No space left" in e for e in result.outcome.events)
    # the disk has room again when the record is written: the log is rewritten whole from memory
    write_record(result, tmp_path, figure=False, folder=folder)
    assert len(list(can.LogReader(str(folder / "can.log")))) == result.frames.count


def test_the_streamed_logs_folder_is_named_by_the_records_own_start(tmp_path: Path, simulated_bench) -> None:
    """CI: the folder was named by a clock read of its own, a second after the record's started_at."""
    variant = _variant(SHORT_S)
    bench, clock, _ = simulated_bench(variant, "worn", 1)
    given: list[str] = []

    def target(started: str) -> Path:
        given.append(started)
        return tmp_path / "can.log"

    result = run_bench_test(bench, clock, variant, BenchOptions(check_gains=False, stream_can_log=target))
    assert given == [result.started_at]


# -- defect 6: the CAN log's capacity ------------------------------------------------------------------------------


def test_a_busy_bus_is_logged_whole(tmp_path: Path) -> None:
    """Defect 6: frames beyond the log's capacity (two a tick) were counted and silently lost."""

    def chatter(link: SlcanSocketRig) -> None:  # another node sends two frames every millisecond
        for k in range(int(SHORT_S * 1000)):
            link.at(0.3 + k * 1e-3, lambda k=k: (link.write_frame(0x300, k.to_bytes(4, "little")),
                                                  link.write_frame(0x301, b"")))

    result, _, _ = run_over_slcan(chatter, SHORT_S, valve="new")
    frames, outcome = result.frames, result.outcome
    assert ran_to_the_end(result) and outcome.frames_dropped == 0
    old_capacity = 2 * int(SHORT_S * 1000) + int(SHORT_S * 1000) // 50 + 4096
    assert frames.count > old_capacity
    assert outcome.other_frames > 14000  # two a millisecond from 0.3 s until the test ended
    doc, folder = _record(result, tmp_path)
    assert len(list(can.LogReader(str(folder / "can.log")))) == frames.count
    assert doc["loop"]["frames_dropped"] == 0


def test_frames_beyond_the_log_maximum_are_reported(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                   simulated_bench) -> None:
    from edc_bench import bench as bench_module

    def with_a_small_log(*args, **kwargs) -> BenchLoop:
        loop = BenchLoop(*args, **kwargs)
        loop.frames = CanFrameLog(3000)
        return loop

    monkeypatch.setattr(bench_module, "BenchLoop", with_a_small_log)
    variant = _variant(SHORT_S)
    bench, clock, _ = simulated_bench(variant, "worn", 1)
    result = run_bench_test(bench, clock, variant, BenchOptions(check_gains=False))
    assert result.frames.count == 3000 and result.outcome.frames_dropped > 10000
    doc, _ = _record(result, tmp_path)
    assert doc["loop"]["frames_dropped"] == result.outcome.frames_dropped
    assert any(f"{result.outcome.frames_dropped} frames after the first 3000" in e for e in doc["loop"]["events"])


def test_frame_log_keeps_ids_kinds_and_lengths_up_to_its_capacity() -> None:
    log = CanFrameLog(10)
    for n in range(13):
        log.add(n * 1e-3, 0x1FFFFFFF if n % 2 else n, bytes([n]) * (n % 9), rx=bool(n % 2), flags=n % 2)
    assert (log.count, log.dropped) == (10, 3)
    assert list(log.can_id[:4]) == [0, 0x1FFFFFFF, 2, 0x1FFFFFFF] and list(log.flags[:3]) == [0, 1, 0]
    assert bytes(log.data[8, :8]) == bytes([8]) * 8 and log.dlc[3] == 3
    fd, remote = CanFrameLog(2), FRAME_REMOTE
    fd.add(0.0, 1, bytes(range(64)), rx=True)  # CAN FD: cut to 8, flagged
    fd.add(0.0, 2, b"", rx=True, flags=remote, dlc=5)  # a remote frame keeps its DLC
    assert bytes(fd.data[0]) == bytes(range(8)) and fd.flags[0] == FRAME_TRUNCATED
    assert fd.dlc[1] == 5 and fd.flags[1] == remote


def test_sent_frames_carry_the_time_they_were_sent(simulated_bench) -> None:
    """Defect 6, second part: a command is stamped when it went out, not when it was due."""
    from edc_bench.runtime.clock import Clock

    class SlowSendClock(Clock):
        """Simulated time in which replies are waited for and every send takes 0.3 ms."""

        def __init__(self, inner: SimulatedClock) -> None:
            self.inner = inner
            self.waits_for_replies = True
            self.kind = inner.kind  # simulated time still

        def now_s(self) -> float:
            return self.inner.now_s()

        def wait_until(self, t_s: float) -> float:
            late = max(0.0, self.inner.now_s() - t_s)
            self.inner.wait_until(t_s)
            return late

        def after_send(self, t_s: float) -> None:
            self.inner.after_send(t_s)

    class SlowBus(can.BusABC):
        def __init__(self, inner, clock) -> None:
            self.inner, self.clock = inner, clock
            super().__init__(channel="slow")

        def send(self, msg, timeout=None) -> None:
            self.inner.send(msg, timeout)
            self.clock.wait_until(self.clock.now_s() + 0.0003)

        def recv(self, timeout=None):
            return self.inner.recv(0.0)  # lockstep: what is there is there, no wall-clock wait

        def _recv_internal(self, timeout):
            return self.inner.recv(0.0), False

    variant = _variant(SHORT_S)
    bench, inner, _ = simulated_bench(variant, "new", 1)
    clock = SlowSendClock(inner)
    result = run_bench_test(SlowBus(bench, inner), clock, variant, BenchOptions(check_gains=False, classify=False))
    frames, start = result.frames, result.outcome.ticks_start_s
    icd = default_icd()
    run_times = [float(frames.t_s[k]) for k in range(frames.count) if not frames.rx[k]
                 and icd.parse_bench_cmd(bytes(frames.data[k])).mode == Mode.RUN]
    scheduled = [start + k * 1e-3 for k in range(len(run_times))]
    offsets = [t - s for t, s in zip(run_times, scheduled, strict=True)]
    assert min(offsets) >= 0.0003 - 1e-9  # the stamp is after the send returned


# -- defects 5, 7 and 8 from the bench's side: a test through `edc-bench rig`'s server with a hostile second host --


class ServerInLockstep:
    """The rig server (edc_bench.sim.server) stepped by the bench's simulated clock, over real sockets."""

    def __init__(self, server, now: list[float]) -> None:
        self.server, self.now = server, now

    #: how long, in real time, the bench's line may take over loopback before the machine counts as too busy
    BUSY_S = 5.0

    def _handled(self) -> int:
        c = self.server.rig.firmware.counters
        return (c.accepted + c.bad_crc + c.bad_length + c.bad_mode + c.repeated_counter + c.stale_counter
                + c.ignored_in_boot)

    def service(self, now_s: float) -> None:
        """Serve until the rig has handled the bench's frame (on a loaded machine it may not be there on the first
        pass), then once more for what else is waiting; a machine too busy to pass a line in seconds skips."""
        self.now[0] = now_s
        before, began = self._handled(), time.monotonic()
        self.server.serve_once(wait_s=0.05)
        while self._handled() == before:
            if time.monotonic() - began > self.BUSY_S:
                pytest.skip(f"the machine was too busy: the bench's line took over {self.BUSY_S:g} s of real time "
                            "over loopback (measured by the test)")
            self.server.serve_once(wait_s=0.05)
        self.server.serve_once(wait_s=0.0)

    def advance_to(self, t_s: float) -> None:
        self.now[0] = t_s
        self.server.serve_once(wait_s=0.0)


def test_a_hostile_second_host_on_the_rig_server_does_not_disturb_the_test(tmp_path: Path) -> None:
    """Another host that sends malformed lines, a remote frame and a valid RUN command of its own, and then never
    reads what the rig sends: the bench's test runs to its end, sees none of it but the remote frame, and the
    rig obeys only the bench."""
    import socket

    from edc_bench.sim.server import SlcanRigServer

    variant = _variant(SHORT_S)
    rig = SimulatedRig(variant, parse_valve_spec("worn", variant), 1)
    now = [0.0]
    log: list[str] = []
    server = SlcanRigServer(rig, clock_s=lambda: now[0], log=log.append, host_queue_bytes=4096)
    _, port = server.listen_tcp("127.0.0.1", 0)
    intruder, intruder_end = socket.socketpair()
    intruder.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
    server.add_host(intruder_end, "intruder")
    icd = default_icd()
    drives_v: list[float] = []

    def intrude(t_s: float) -> None:
        if t_s >= FAULT_AT_S and not drives_v:
            intruder.sendall(b"O\rt-2080000000000000000\rt1218" + b"00" * 8 + b"FF\rt_12800\rr3004\r")
            intruder.sendall(format_frame_line(SlcanFrame(BENCH_CMD_ID, icd.make_bench_cmd(9, Mode.RUN, 20.0, 1.0))))
            drives_v.append(rig.plant.drive_v)
        elif drives_v:
            drives_v.append(rig.plant.drive_v)

    class Watching(ServerInLockstep):
        def advance_to(self, t_s: float) -> None:
            super().advance_to(t_s)
            intrude(t_s)

    session = ClosingBus(open_bus({"interface": "slcan", "channel": f"socket://127.0.0.1:{port}"}, icd.bitrate))
    with session as bus:
        clock = SimulatedClock(Watching(server, now))
        result = run_bench_test(bus, clock, variant, BenchOptions(check_gains=False))
    assert ran_to_the_end(result), result.outcome
    assert result.outcome.bus_bad_lines == 0  # no malformed line reached the bench
    assert result.outcome.other_frames == 1  # the remote frame, forwarded as a remote frame
    assert max(drives_v) < 15.0  # the intruder's 20 V was never applied
    stats = {s.name: s for s in server.host_stats()}
    assert stats["intruder"].malformed_lines == 3 and stats["intruder"].refused_bench_cmds == 1
    assert stats["intruder"].dropped_lines > 0  # it never read: its frames were dropped, the test went on
    assert any("BENCH_CMD refused" in line for line in log) and any("not reading" in line for line in log)
    doc, folder = _record(result, tmp_path)
    assert len(list(can.LogReader(str(folder / "can.log")))) == result.frames.count
    intruder.close()


class _HeldOffSocket:
    """The bench's socket, with the bench held off the CPU for ``held_s`` inside each send (a busy PC)."""

    def __init__(self, sock, held_s: float) -> None:
        self.sock, self.held_s = sock, held_s

    def send(self, data) -> int:
        sent = self.sock.send(data)
        time.sleep(self.held_s)  # a preemption, not a wait for anything: what a loaded PC does to the bench
        return sent

    def __getattr__(self, name: str):
        return getattr(self.sock, name)  # recv, fileno, ...: as they are


def _slcan_pair() -> tuple[BufferedSlcanBus, "socket.socket"]:
    import socket

    listener = socket.create_server(("127.0.0.1", 0))
    bus = open_bus({"interface": "slcan", "channel": f"socket://127.0.0.1:{listener.getsockname()[1]}"},
                   default_icd().bitrate)
    peer, _ = listener.accept()
    listener.close()
    return bus, peer


def test_a_send_held_off_the_cpu_past_its_timeout_is_not_a_bus_error() -> None:
    """CI's run beside two busy loops aborted a test with a bus error: pyserial's write raised its 20 ms timeout
    after the line had gone out, because the bench was off the CPU meanwhile. A sent line is sent."""
    bus, peer = _slcan_pair()
    try:
        # where python-can's slcan and pyserial write, and where the bus reads
        bus._socket = bus.serialPortOrig._socket = _HeldOffSocket(bus._socket, 3 * BufferedSlcanBus.send_timeout_s)
        bus.send(can.Message(arbitration_id=BENCH_CMD_ID, data=bytes(8), is_extended_id=False))
        peer.settimeout(5)
        received = b""
        while not received.endswith(b"\r" + format_frame_line(SlcanFrame(BENCH_CMD_ID, bytes(8)))):
            received += peer.recv(100)  # the adapter's set-up lines, then the frame
    finally:
        close_quietly(bus)
        peer.close()


def test_a_peer_that_stops_reading_still_ends_a_send_within_its_timeout() -> None:
    import socket

    bus, peer = _slcan_pair()
    try:
        bus._socket.setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, 4096)
        message = can.Message(arbitration_id=BENCH_CMD_ID, data=bytes(8), is_extended_id=False)
        with pytest.raises(can.CanOperationError, match="slcan send gave up: the adapter took no more bytes"):
            for _ in range(1_000_000):  # the peer reads nothing: the socket's buffers fill, then a send gives up
                bus.send(message)
    finally:
        close_quietly(bus)
        peer.close()
