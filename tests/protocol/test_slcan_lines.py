"""slcan frame lines, strictly (edc_bench.protocol.slcan): property-based, any bytes at all."""

from __future__ import annotations

from hypothesis import given, settings
from hypothesis import strategies as st

from edc_bench.protocol import RIG_FEEDBACK_ID, ProtocolError, default_icd
from edc_bench.protocol.slcan import (
    EXTENDED_ID_MAX,
    STANDARD_ID_MAX,
    SlcanFrame,
    format_frame_line,
    parse_frame_line,
)


@st.composite
def frames(draw: st.DrawFn) -> SlcanFrame:
    extended, remote = draw(st.booleans()), draw(st.booleans())
    can_id = draw(st.integers(0, EXTENDED_ID_MAX if extended else STANDARD_ID_MAX))
    if remote:
        return SlcanFrame(can_id, b"", extended, True, draw(st.integers(0, 8)))
    return SlcanFrame(can_id, draw(st.binary(max_size=8)), extended)


@given(frames())
def test_every_frame_survives_its_line(frame: SlcanFrame) -> None:
    line = format_frame_line(frame)
    assert line.endswith(b"\r") and parse_frame_line(line[:-1]) == frame


@settings(max_examples=500)
@given(st.binary(max_size=40) | st.builds(lambda f, cut, junk: format_frame_line(f)[:-1][:cut] + junk,
                                           frames(), st.integers(0, 30), st.binary(max_size=3)))
def test_any_bytes_are_a_frame_only_if_exactly_a_frame_line(line: bytes) -> None:
    frame = parse_frame_line(line)  # never raises
    if frame is not None:
        assert len(frame.data) <= 8 and frame.length <= 8
        assert frame.can_id <= (EXTENDED_ID_MAX if frame.extended else STANDARD_ID_MAX)
        # the line is the frame's own line, but for the case of its hex digits
        assert line[:1] + line[1:].upper() == format_frame_line(frame)[:-1]


def test_what_pythons_int_would_let_through_is_refused() -> None:
    payload = b"00" * 8
    for line in (b"t-208" + payload, b"t+12" + b"8" + payload, b"t_128" + payload, b"t 128" + payload,
                 b"t1218" + payload + b"00", b"t1218" + payload[:-2], b"t8001" + b"00", b"T200000001" + b"00",
                 b"t1219" + payload, b"r1218" + b"00", b"t1218" + payload[:-1] + b"G", b"t\xff218" + payload):
        assert parse_frame_line(line) is None, line


ICD = default_icd()
REPLY = ICD.make_rig_feedback(0x5A, amp_enabled=True, watchdog_tripped=False, over_current=False, lvdt_fault=False,
                              travel_limit=False, position_mm=8.25, current_a=1.5)
REPLY_LINE = format_frame_line(SlcanFrame(RIG_FEEDBACK_ID, REPLY))[:-1]


@settings(max_examples=400)
@given(st.integers(0, len(REPLY_LINE) - 1), st.integers(0, 255))
def test_a_damaged_reply_line_is_never_a_usable_reply(position: int, value: int) -> None:
    """One byte of a reply's line changed: no frame, another frame, or a payload the E2E check refuses."""
    line = REPLY_LINE[:position] + bytes([value]) + REPLY_LINE[position + 1:]
    frame = parse_frame_line(line)
    if frame is None or frame.can_id != RIG_FEEDBACK_ID or frame.extended or frame.remote:
        return
    if frame.data == REPLY:  # the same reply (a hex digit's case changed, or no change at all)
        return
    try:
        ICD.parse_rig_feedback(frame.data)
    except ProtocolError:
        return
    raise AssertionError(f"{line!r} passed as a reply")
