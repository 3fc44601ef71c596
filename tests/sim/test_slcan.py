"""The slcan device protocol, pure."""

from __future__ import annotations

from edc_bench.sim.slcan import ERROR, OK, SlcanDevice, SlcanFrame


def test_open_send_and_close() -> None:
    dev = SlcanDevice()
    frames, reply = dev.feed(b"C\rS6\rO\r")
    assert (frames, reply) == ([], OK * 3)
    assert dev.is_open and dev.bitrate_code == "6"
    frames, reply = dev.feed(b"t1208" + b"0102030405060708\r")
    assert frames == [SlcanFrame(0x120, bytes.fromhex("0102030405060708"))]
    assert reply == b"z\r"
    frames, reply = dev.feed(b"T000007202AABB\r")
    assert frames == [SlcanFrame(0x720, b"\xaa\xbb", extended=True)]
    assert reply == b"Z\r"


def test_frames_split_across_reads_are_reassembled() -> None:
    dev = SlcanDevice()
    dev.feed(b"O\r")
    assert dev.feed(b"t12") == ([], b"")
    frames, reply = dev.feed(b"02ABCD\rt1210\r")
    assert frames == [SlcanFrame(0x120, b"\xab\xcd"), SlcanFrame(0x121, b"")]


def test_errors_answer_bel() -> None:
    dev = SlcanDevice()
    assert dev.feed(b"t1201AA\r") == ([], ERROR)  # channel not open
    dev.feed(b"O\r")
    assert dev.feed(b"t12")[1] == b""
    assert dev.feed(b"9\r") == ([], ERROR)  # malformed frame (dlc 9)
    assert dev.feed(b"t1202AA\r") == ([], ERROR)  # too few data bytes
    assert dev.feed(b"Q\r") == ([], ERROR)  # unknown command
    assert dev.feed(b"x" * 100)[1] == ERROR  # garbage without terminator
    assert dev.errors == 5


def test_version_and_format() -> None:
    dev = SlcanDevice()
    assert dev.feed(b"V\r")[1] == b"V1013\r"
    assert SlcanDevice.format_frame(0x121, bytes.fromhex("3f0511102730f800")) == b"t12183F0511102730F800\r"
    assert SlcanDevice.format_frame(0x1ABCDEF, b"\x01", extended=True) == b"T01ABCDEF101\r"
