"""Property-based tests (hypothesis) of the rig's slcan parser, alone and in front of the firmware.

The expected frames come from a reference written here from the slcan line
rules (regular expressions), not from the parser under test.
"""

from __future__ import annotations

import itertools
import re

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from edc_bench.config import Variant
from edc_bench.physics.valve import parse_valve_spec
from edc_bench.protocol import (
    BENCH_CMD_ID,
    RIG_FEEDBACK_ID,
    E2EError,
    Mode,
    ProtocolError,
    RigState,
    default_icd,
    e2e_crc,
)
from edc_bench.sim.rig import SimulatedRig
from edc_bench.sim.slcan import MAX_LINE, SlcanDevice, SlcanFrame
from firmware_proto.firmware import RigFirmware

FAST = settings(max_examples=200, deadline=None)
_DATA_LINE = re.compile(rb"\n*(?:t([0-9A-Fa-f]{3})|T([0-9A-Fa-f]{8}))([0-8])((?:[0-9A-Fa-f]{2})*)")
_REMOTE_LINE = re.compile(rb"\n*(?:r([0-9A-Fa-f]{3})|R([0-9A-Fa-f]{8}))([0-8])")
#: bytes that lenient parsers take for part of a number, or that end or split a line
TRICKY = b"0123456789abcdefABCDEF+-_ x.\n\r\a\x00\xff"


def reference_frame(line: bytes) -> SlcanFrame | None:
    """The frame a line (without its CR) is, by the slcan rules, or None."""
    if len(line) > MAX_LINE:
        return None
    if match := _DATA_LINE.fullmatch(line):
        standard, extended, dlc, data = match.groups()
        frame = SlcanFrame(int(standard or extended, 16), bytes.fromhex(data.decode()), extended is not None)
        ok = len(data) == 2 * int(dlc)
    elif match := _REMOTE_LINE.fullmatch(line):
        standard, extended, dlc = match.groups()
        frame = SlcanFrame(int(standard or extended, 16), b"", extended is not None, remote=True, dlc=int(dlc))
        ok = True
    else:
        return None
    return frame if ok and frame.can_id <= (0x1FFFFFFF if frame.extended else 0x7FF) else None


def reference_frames(stream: bytes) -> list[SlcanFrame]:
    """The frames a device opened with ``O`` takes from ``stream``: its complete lines, while open and not
    listen-only."""
    frames, open_, listen_only = [], True, False
    for line in stream.split(b"\r")[:-1]:
        command = line.lstrip(b"\n") if len(line) <= MAX_LINE else None
        if command in (b"O", b"L", b"C"):
            open_, listen_only = command != b"C", command == b"L"
        elif (frame := reference_frame(line)) is not None and open_ and not listen_only:
            frames.append(frame)
    return frames


# strategies made once: building them inside a composite costs more than drawing from them
_KINDS = st.sampled_from("tTrR")
_IDS = {False: st.integers(0, 0x7FF), True: st.integers(0, 0x1FFFFFFF)}
_DLCS = st.integers(0, 8)
_EIGHT_BYTES = st.binary(min_size=8, max_size=8)
_CASE_MASKS = st.integers(0, (1 << 26) - 1)  # which characters of a line are in lower case: one draw, not one each
_POSITIONS = st.integers(0, 1 << 16)
_MUTATION_BYTES = st.sampled_from(TRICKY) | st.integers(0, 255)
_MUTATION_KINDS = st.sampled_from(["replace", "insert", "delete"])
_MUTATION_COUNTS = st.integers(1, 3)


@st.composite
def frame_lines(draw: st.DrawFn) -> bytes:
    """A well-formed frame line of any kind, hex digits in either case."""
    kind = draw(_KINDS)
    extended = kind in "TR"
    can_id, dlc = draw(_IDS[extended]), draw(_DLCS)
    text = f"{kind}{can_id:0{8 if extended else 3}X}{dlc}"
    if kind in "tT":
        text += draw(_EIGHT_BYTES)[:dlc].hex()
    lower = draw(_CASE_MASKS)
    return "".join(c.lower() if lower >> k & 1 else c for k, c in enumerate(text)).encode()


@st.composite
def mutated(draw: st.DrawFn, line: st.SearchStrategy[bytes]) -> bytes:
    """A line with one to three bytes replaced, inserted or deleted."""
    text = bytearray(draw(line))
    for _ in range(draw(_MUTATION_COUNTS)):
        at = draw(_POSITIONS) % (len(text) + 1)
        byte, how = draw(_MUTATION_BYTES), draw(_MUTATION_KINDS)
        if how == "insert" or at == len(text):
            text.insert(at, byte)
        elif how == "replace":
            text[at] = byte
        else:
            del text[at]
    return bytes(text)


lines = st.one_of(frame_lines(), mutated(frame_lines()), st.binary(max_size=30),
                  st.sampled_from([b"O", b"L", b"C", b"V", b"F", b"S6", b"\n" * 70 + b"t1200", b"x" * 80]))
streams = st.lists(st.tuples(lines, st.sampled_from([b"\r", b"\r\n", b""])), max_size=6).map(
    lambda items: b"".join(line + end for line, end in items))


def chunks(stream: bytes, cuts: list[int]) -> list[bytes]:
    """``stream`` cut at the given positions."""
    edges = [0, *sorted({c % (len(stream) + 1) for c in cuts}), len(stream)]
    return [stream[a:b] for a, b in itertools.pairwise(edges)]


def well_formed(frame: SlcanFrame) -> bool:
    """Id in range, DLC 0-8, and as many data bytes as the DLC says (none in a remote frame)."""
    return (0 <= frame.can_id <= (0x1FFFFFFF if frame.extended else 0x7FF) and 0 <= frame.length <= 8
            and len(frame.data) == (0 if frame.remote else frame.length))


@FAST
@given(stream=streams, cuts=st.lists(st.integers(0, 400), max_size=8))
def test_any_bytes_in_any_chunks_give_exactly_the_well_formed_frame_lines(stream: bytes, cuts: list[int]) -> None:
    device = SlcanDevice()
    device.feed(b"O\r")
    frames, reply = [], b""
    for chunk in chunks(stream, cuts):
        got, answer = device.feed(chunk)
        frames, reply = frames + got, reply + answer
    assert all(well_formed(frame) for frame in frames)
    assert frames == reference_frames(stream)  # each from a line that is exactly a valid frame line
    whole = SlcanDevice()
    whole.feed(b"O\r")
    assert whole.feed(stream) == (frames, reply)  # however the stream was cut


@FAST
@given(data=st.binary(max_size=200), cuts=st.lists(st.integers(0, 400), max_size=8))
def test_arbitrary_bytes_never_raise_and_give_only_well_formed_frames(data: bytes, cuts: list[int]) -> None:
    device = SlcanDevice()
    device.feed(b"O\r")
    for chunk in chunks(data, cuts):
        frames, _ = device.feed(chunk)
        assert all(well_formed(frame) for frame in frames)


# -- through the firmware: an invalid frame alone never drives ----------------------------------------------------

ICD = default_icd()


@pytest.fixture(scope="module")
def rig(variant: Variant) -> SimulatedRig:
    rig = SimulatedRig(variant, parse_valve_spec("new", variant), seed=0)
    rig.advance_to(BOOTED_S)
    return rig


BOOTED_S = 0.25


def boot_afresh(rig: SimulatedRig) -> None:
    """Give the rig a new firmware on the same hardware, booted and READY at ``BOOTED_S``: 0 V, no counter yet
    (cheaper than a new rig for every example)."""
    rig.firmware = RigFirmware(rig.hardware, rig.firmware.limits, start_s=0.0, icd=ICD)
    rig.firmware.on_time(BOOTED_S)
    assert rig.firmware.state is RigState.READY and rig.plant.drive_v == 0.0


def bench_cmd_line(payload: bytes) -> bytes:
    return f"t{BENCH_CMD_ID:03X}{len(payload)}{payload.hex().upper()}".encode()


def with_mode(payload: bytes, mode: int) -> bytes:
    """The payload with another Mode byte and its CRC made right again."""
    changed = bytearray(payload)
    changed[2] = mode
    changed[0] = e2e_crc(ICD.bench_cmd_data_id, bytes(changed))
    return bytes(changed)


valid_runs = st.builds(lambda counter, drive_v: ICD.make_bench_cmd(counter, Mode.RUN, drive_v, 10.0),
                       st.integers(0, 255), st.floats(0.5, 24.0) | st.floats(-24.0, -0.5))
#: BENCH_CMD lines fuzzed, mutated from a valid RUN, a valid RUN with junk after it, of an undefined Mode with a
#: correct CRC, or of another DLC
invalid_bench_cmd_lines = st.one_of(
    mutated(valid_runs.map(bench_cmd_line)),
    st.builds(bytes.__add__, valid_runs.map(bench_cmd_line), st.binary(min_size=1, max_size=4).map(
        lambda junk: junk.replace(b"\r", b"0"))),
    st.builds(with_mode, valid_runs, st.integers(2, 255)).map(bench_cmd_line),
    st.builds(lambda payload, dlc: bench_cmd_line(payload[:dlc]), valid_runs, st.integers(0, 7)),
    st.binary(min_size=8, max_size=8).map(bench_cmd_line),
    st.text("0123456789ABCDEFabcdef+-_ ", max_size=20).map(lambda digits: b"t1208" + digits.encode()),
)


def is_valid_command(line: bytes) -> bool:
    """Whether the line is exactly a BENCH_CMD frame line carrying a valid command (CRC, length, Mode)."""
    frame = reference_frame(line)
    if frame is None or frame.can_id != BENCH_CMD_ID or frame.extended or frame.remote:
        return False
    try:
        return ICD.parse_bench_cmd(frame.data).mode in (Mode.SAFE, Mode.RUN)
    except (E2EError, ProtocolError):
        return False


@FAST
@given(line=invalid_bench_cmd_lines)
def test_an_invalid_bench_cmd_line_never_drives_the_rig(rig: SimulatedRig, line: bytes) -> None:
    boot_afresh(rig)
    device = SlcanDevice()
    device.feed(b"O\r")
    frames, _ = device.feed(line + b"\r")
    out = [f for frame in frames if not (frame.extended or frame.remote)
           for f in rig.receive(frame.can_id, frame.data, BOOTED_S)]
    # a mutation may leave a valid command (a hex digit's case), or cut one off with a CR of its own (the device
    # reads the lines a CR ends): that one is obeyed
    if any(is_valid_command(part) for part in line.split(b"\r")):
        return
    assert rig.plant.drive_v == 0.0 and rig.firmware.state is RigState.READY
    assert not [can_id for can_id, _ in out if can_id == RIG_FEEDBACK_ID]  # ignored, with no reply
