"""The bench's slcan reader (BufferedSlcanBus) on a real socket, fed any bytes at all (property-based).

Never an exception for what the other end sends, never a frame that was not
exactly a frame line in the stream, and every frame of a clean stream, in
order.
"""

from __future__ import annotations

import socket
from collections.abc import Iterator
from pathlib import Path

import can
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from edc_bench.protocol.slcan import EXTENDED_ID_MAX, STANDARD_ID_MAX, SlcanFrame, format_frame_line
from edc_bench.runtime.bus import BufferedSlcanBus


@pytest.fixture(scope="module")
def reader() -> Iterator[tuple[BufferedSlcanBus, socket.socket]]:
    """The bench's bus and the far end of its TCP connection."""
    listener = socket.create_server(("127.0.0.1", 0))
    bus = BufferedSlcanBus(f"socket://127.0.0.1:{listener.getsockname()[1]}", bitrate=500000, sleep_after_open=0)
    conn, _ = listener.accept()
    listener.close()
    yield bus, conn
    conn.close()
    bus.shutdown()


@st.composite
def frame_lines(draw: st.DrawFn) -> bytes:
    extended, remote = draw(st.booleans()), draw(st.booleans())
    can_id = draw(st.integers(0, EXTENDED_ID_MAX if extended else STANDARD_ID_MAX))
    frame = SlcanFrame(can_id, b"", extended, True, draw(st.integers(0, 8))) if remote else \
        SlcanFrame(can_id, draw(st.binary(max_size=8)), extended)
    return format_frame_line(frame)


SENTINEL = format_frame_line(SlcanFrame(0x1FFFFFFF, b"sentinel", extended=True))


def _all_received(bus: BufferedSlcanBus, stream: bytes, conn: socket.socket) -> list[can.Message]:
    """What the bus reads of ``stream``: up to a sentinel frame sent after it (no waiting on a clock)."""
    bus._buffer.clear()  # a fresh stream per example: nothing left over from the last one
    bus._lines.clear()
    conn.sendall(stream + b"\r" + SENTINEL)  # the CR ends a partial line at the end: a (bad) line of its own
    received = []
    while (msg := bus.recv(1.0)) is not None:
        if msg.arbitration_id == 0x1FFFFFFF and bytes(msg.data) == b"sentinel":
            return received
        received.append(msg)
    raise AssertionError("the sentinel frame never came")


def _occurs(line: bytes, stream: bytes) -> bool:
    """``line`` is in ``stream`` as sent, but for the case of its hex digits."""
    upper = stream.upper()
    start = upper.find(line[1:])
    while start > 0:
        if stream[start - 1] == line[0]:
            return True
        start = upper.find(line[1:], start + 1)
    return False


def _line(msg: can.Message) -> bytes:
    return format_frame_line(SlcanFrame(msg.arbitration_id, bytes(msg.data) if not msg.is_remote_frame else b"",
                                        msg.is_extended_id, msg.is_remote_frame,
                                        msg.dlc if msg.is_remote_frame else None))[:-1]


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.lists(frame_lines() | st.binary(min_size=1, max_size=30), max_size=8))
def test_any_bytes_never_raise_and_never_invent_a_frame(reader, chunks: list[bytes]) -> None:
    bus, conn = reader
    stream = b"".join(chunks)
    for msg in _all_received(bus, stream, conn):
        assert len(msg.data) <= 8
        assert _occurs(_line(msg), stream), msg


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.lists(frame_lines(), min_size=1, max_size=10))
def test_a_clean_stream_gives_every_frame_in_order(reader, lines: list[bytes]) -> None:
    bus, conn = reader
    received = _all_received(bus, b"".join(lines), conn)
    assert [_line(m) + b"\r" for m in received] == lines


def test_a_stream_of_noise_without_line_ends_cannot_hold_the_reader(reader) -> None:
    """A peer that keeps sending bytes but never a line end: recv(0) reads one chunk and returns, leaving the rest
    for later (the loop's frame budget counts frames, so bytes must not hold the reader either)."""
    import select
    import threading

    bus, conn = reader
    bus._pending.clear()
    bus._lines.clear()
    noise = b"\x80" * 300_000 + b"\a" * 1000
    sender = threading.Thread(target=conn.sendall, args=(noise,))
    sender.start()
    while not select.select([bus._socket], [], [], 1.0)[0]:
        pass
    before = bus.bad_lines
    assert bus.recv(0.0) is None
    assert bus.bad_lines == before + 1  # the overlong run counted once
    assert select.select([bus._socket], [], [], 1.0)[0]  # the rest of the noise was left for later reads
    while bus.recv(0.0) is not None or select.select([bus._socket], [], [], 0.2)[0]:
        pass  # drain it all
    sender.join()
    assert _all_received(bus, b"", conn) == []  # and frames after it are read again (the sentinel came)


def test_a_peer_that_stops_reading_makes_a_send_fail_not_hang() -> None:
    """Sends give up after send_timeout_s: the loop aborts (and the rig's watchdog acts) instead of blocking."""
    listener = socket.create_server(("127.0.0.1", 0))
    bus = BufferedSlcanBus(f"socket://127.0.0.1:{listener.getsockname()[1]}", bitrate=500000, sleep_after_open=0)
    conn, _ = listener.accept()  # and never read from
    conn.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
    bus._socket.setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, 4096)
    msg = can.Message(arbitration_id=0x120, data=bytes(8), is_extended_id=False)
    with pytest.raises(can.CanOperationError):
        for _ in range(100_000):  # the kernel's buffers fill within a few thousand frames
            bus.send(msg)
    bus.shutdown()
    conn.close()
    listener.close()


def test_the_loop_reads_what_the_adapter_skipped_through_one_typed_interface() -> None:
    """#54: the loop read the slcan bus's counters by getattr; a bus that keeps none gives zeros."""
    from edc_bench.runtime.adapter_counts import AdapterCounts, CountsAdapterErrors, adapter_counts
    from edc_bench.runtime.bus import BufferedSlcanBus

    assert issubclass(BufferedSlcanBus, CountsAdapterErrors)
    assert adapter_counts(object()) == AdapterCounts()
    loop_source = (Path(__file__).parents[2] / "edc_bench" / "runtime" / "loop.py").read_text(encoding="utf-8")
    assert "getattr(self.bus" not in loop_source
