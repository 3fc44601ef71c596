"""The slcan device protocol, pure."""

from __future__ import annotations

import pytest

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


def _open_device() -> SlcanDevice:
    dev = SlcanDevice()
    assert dev.feed(b"O\r") == ([], OK)
    return dev


@pytest.mark.parametrize("line", [
    b"t-2080102030405060708",  # a sign before the id: int(x, 16) takes it
    b"t+1280102030405060708",
    b"t1_280102030405060708",  # an underscore in the id
    b"t 1280102030405060708",  # a space in the id
    b"t12080102030405060708FF",  # junk after the payload
    b"t1208010203040506070",  # one hex digit short
    b"t12080102030405060x08",  # not hex in the payload
    b"t120 0102030405060708",  # a DLC that is not a digit
    b"t1209010203040506070809",  # DLC 9
    b"t8000",  # a standard id above 0x7FF
    b"T200000000",  # an extended id above 0x1FFFFFFF
    b"T1FFFFFF_0",
    b"r1202AA",  # a remote frame carries no data
    b"r12",
    b"t",
    b"O1",  # arguments where a command takes none
    b"S9x",
])
def test_malformed_lines_answer_bel_and_yield_no_frame(line: bytes) -> None:
    dev = _open_device()
    assert dev.feed(line + b"\r") == ([], ERROR)
    assert dev.errors == 1


def test_limits_of_well_formed_lines_are_frames() -> None:
    dev = _open_device()
    frames, reply = dev.feed(b"t7FF0\rT1FFFFFFF80102030405060708\rt120201ab\rr1203\rR000007208\r")
    assert frames == [SlcanFrame(0x7FF, b""), SlcanFrame(0x1FFFFFFF, bytes(range(1, 9)), extended=True),
                      SlcanFrame(0x120, b"\x01\xab"), SlcanFrame(0x120, b"", remote=True, dlc=3),
                      SlcanFrame(0x720, b"", extended=True, remote=True, dlc=8)]
    assert reply == b"z\rZ\rz\rz\rZ\r"


def test_the_tail_of_an_overlong_line_is_not_a_frame() -> None:
    dev = _open_device()
    assert dev.feed(b"x" * 70) == ([], ERROR)  # answered once, when it overflows
    assert dev.feed(b"t1200\r") == ([], b"")  # still the same line: discarded up to its CR
    assert dev.feed(b"t1200\r") == ([SlcanFrame(0x120, b"")], b"z\r")
    assert dev.feed(b"\n" * 70 + b"t1200\r") == ([], ERROR)  # too long, whether it comes in one piece or not


def test_status_flags_report_a_data_overrun_once() -> None:
    dev = _open_device()
    assert dev.feed(b"F\r") == ([], b"F00\r")
    dev.overrun = True
    assert dev.feed(b"F\r") == ([], b"F08\r")  # bit 3: data overrun
    assert dev.feed(b"F\r") == ([], b"F00\r")  # reading the flags clears them


def test_a_refused_frame_is_answered_bel_in_its_place() -> None:
    dev = _open_device()
    frames, reply = dev.feed(b"t1200\rt1210\rV\r", admit=lambda frame: frame.can_id != 0x120)
    assert frames == [SlcanFrame(0x121, b"")]
    assert reply == ERROR + b"z\rV1013\r"
