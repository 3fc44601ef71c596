"""ICD v1: the DBC, the CRC, exact frame bytes, and the fast codec against cantools."""

from __future__ import annotations

import math

import cantools
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from edc_bench.errors import EdcBenchError
from edc_bench.protocol import FaultCode, Icd, Mode, RigState, crc8_sae_j1850, default_icd
from edc_bench.protocol.errors import E2EError, ProtocolError
from firmware_proto import dbc_path

# firmware_proto/PROTOCOL.md "Frames", written out independently of the DBC
ICD_TABLE = {
    "BENCH_CMD": (0x120, {
        "CRC": (8, False, 1, ""), "Counter": (8, False, 1, ""), "Mode": (8, False, 1, ""),
        "DriveVoltage": (16, True, 0.001, "V"), "RackReference": (16, False, 0.001, "mm"),
    }),
    "RIG_FEEDBACK": (0x121, {
        "CRC": (8, False, 1, ""), "Counter": (8, False, 1, ""), "AmpEnabled": (1, False, 1, ""),
        "WatchdogTripped": (1, False, 1, ""), "OverCurrent": (1, False, 1, ""), "LvdtFault": (1, False, 1, ""),
        "TravelLimit": (1, False, 1, ""), "RackPosition": (16, False, 0.001, "mm"),
        "CoilCurrent": (16, True, 0.001, "A"),
    }),
    "RIG_HEARTBEAT": (0x720, {
        "State": (8, False, 1, ""), "FaultCode": (8, False, 1, ""), "FwMajor": (8, False, 1, ""),
        "FwMinor": (8, False, 1, ""), "SupplyVoltage": (16, False, 0.01, "V"),
    }),
}


@pytest.fixture(scope="module")
def db() -> cantools.database.can.Database:
    return cantools.database.load_file(str(dbc_path()))


def test_dbc_is_packaged_and_found() -> None:
    path = dbc_path()
    assert path.is_file()
    assert path.parent.name == "protocol"


@pytest.mark.parametrize("name", sorted(ICD_TABLE))
def test_dbc_matches_icd_table(db, name: str) -> None:
    frame_id, signals = ICD_TABLE[name]
    message = db.get_message_by_name(name)
    assert message.frame_id == frame_id
    assert not message.is_extended_frame
    assert message.length == 8
    assert {s.name for s in message.signals} == set(signals)
    for signal in message.signals:
        length, signed, scale, unit = signals[signal.name]
        assert (signal.length, signal.is_signed, signal.scale, signal.unit or "") == (length, signed, scale, unit)
        assert signal.byte_order == "little_endian"
    if name != "RIG_HEARTBEAT":
        assert message.get_signal_by_name("CRC").start == 0  # CRC is byte 0
        assert message.dbc.attributes["E2EDataId"].value == frame_id & 0xFF


def test_dbc_network_attributes(icd: Icd) -> None:
    assert icd.bitrate == 500_000
    assert icd.watchdog_ms == 20
    assert icd.version == (1, 0)


def test_enums_match_dbc_value_tables(icd: Icd) -> None:
    assert icd.choices("BENCH_CMD", "Mode") == {m.value: m.name for m in Mode}
    assert icd.choices("RIG_HEARTBEAT", "State") == {s.value: s.name for s in RigState}
    assert icd.choices("RIG_HEARTBEAT", "FaultCode") == {f.value: f.name for f in FaultCode}


def test_crc8_sae_j1850_check_value() -> None:
    assert crc8_sae_j1850(b"123456789") == 0x4B
    assert crc8_sae_j1850(b"") == 0x00  # init 0xFF, xorout 0xFF


def test_bench_cmd_exact_bytes(icd: Icd) -> None:
    payload = icd.make_bench_cmd(counter=1, mode=Mode.RUN, drive_v=-1.5, reference_mm=10.0)
    # counter 01, mode 01, -1500 = 0xFA24, 10000 = 0x2710, pad 00; CRC over 0x20 + bytes 1..7
    assert payload == bytes.fromhex("48010124fa102700")
    assert payload[0] == crc8_sae_j1850(bytes([0x20]) + payload[1:])


def test_rig_feedback_exact_bytes(icd: Icd) -> None:
    payload = icd.make_rig_feedback(
        5, amp_enabled=True, watchdog_tripped=False, over_current=False, lvdt_fault=False,
        travel_limit=True, position_mm=10.0, current_a=-2.0,
    )
    # flags byte: bit0 AmpEnabled, bit4 TravelLimit; -2000 = 0xF830
    assert payload == bytes.fromhex("3f0511102730f800")
    assert payload[0] == crc8_sae_j1850(bytes([0x21]) + payload[1:])


def test_heartbeat_exact_bytes(icd: Icd) -> None:
    payload = icd.make_heartbeat(RigState.READY, FaultCode.NONE, 1, 0, 24.0)
    assert payload == bytes.fromhex("0100010060090000")
    assert icd.parse_heartbeat(payload) == (RigState.READY, FaultCode.NONE, 1, 0, 24.0)


def test_every_single_bit_corruption_is_detected(icd: Icd) -> None:
    payload = icd.make_bench_cmd(7, Mode.RUN, 3.3, 12.5)
    for bit in range(64):
        corrupted = bytearray(payload)
        corrupted[bit // 8] ^= 1 << (bit % 8)
        with pytest.raises(E2EError):
            icd.parse_bench_cmd(corrupted)


def test_crc_depends_on_data_id(icd: Icd) -> None:
    # same bytes 1..7 in both messages must not share a CRC
    cmd = icd.make_bench_cmd(0, 0, 0.0, 0.0)
    fb = icd.make_rig_feedback(0, amp_enabled=False, watchdog_tripped=False, over_current=False,
                               lvdt_fault=False, travel_limit=False, position_mm=0.0, current_a=0.0)
    assert cmd[1:] == fb[1:] and cmd[0] != fb[0]


@pytest.mark.parametrize(
    ("value", "match"),
    [(40.0, r'"DriveVoltage" value in \[-32.768, 32.767\].*got 40.0'), (math.nan, "DriveVoltage"),
     (math.inf, "DriveVoltage")],
)
def test_out_of_range_drive_is_refused_with_message(icd: Icd, value: float, match: str) -> None:
    with pytest.raises(ProtocolError, match=match):
        icd.make_bench_cmd(0, Mode.RUN, value, 10.0)


def test_mode_outside_value_table_is_refused(icd: Icd) -> None:
    with pytest.raises(ProtocolError, match="Mode"):
        icd.make_bench_cmd(0, 2, 0.0, 10.0)


def test_wrong_length_is_refused(icd: Icd) -> None:
    with pytest.raises(ProtocolError, match="Expected 8 bytes"):
        icd.parse_rig_feedback(b"\x00" * 7)


def _values(message) -> st.SearchStrategy[dict[str, float]]:
    fields = {}
    for s in message.signals:
        lo = -(1 << (s.length - 1)) if s.is_signed else 0
        hi = (1 << (s.length - 1)) - 1 if s.is_signed else (1 << s.length) - 1
        if s.minimum is not None:
            lo = max(lo, round(s.minimum / s.scale))
            hi = min(hi, round(s.maximum / s.scale))
        fields[s.name] = st.integers(lo, hi).map(lambda raw, sc=s.scale: raw * sc)
    return st.fixed_dictionaries(fields)


@pytest.mark.parametrize("name", sorted(ICD_TABLE))
def test_fast_codec_agrees_with_cantools_on_every_signal(db, icd: Icd, name: str) -> None:
    message = db.get_message_by_name(name)
    layout = {"BENCH_CMD": icd.bench_cmd, "RIG_FEEDBACK": icd.rig_feedback, "RIG_HEARTBEAT": icd.rig_heartbeat}[name]
    assert layout.signal_names == tuple(s.name for s in message.signals)

    @settings(max_examples=300, deadline=None)
    @given(_values(message))
    def check(values: dict[str, float]) -> None:
        ours = layout.encode(*(values[n] for n in layout.signal_names))
        theirs = message.encode(values, scaling=True, strict=True)
        assert ours == theirs
        decoded = dict(zip(layout.signal_names, layout.decode(ours), strict=True))
        reference = message.decode(theirs, decode_choices=False)
        for key, value in reference.items():
            assert decoded[key] == pytest.approx(value, abs=1e-9), key

    check()


@settings(max_examples=500, deadline=None)
@given(st.binary(min_size=0, max_size=12))
def test_parsing_arbitrary_bytes_raises_only_project_errors(payload: bytes) -> None:
    icd = default_icd()
    for parse in (icd.parse_bench_cmd, icd.parse_rig_feedback, icd.parse_heartbeat):
        try:
            parse(payload)
        except EdcBenchError:
            pass


_UNALIGNED_DBC = """VERSION ""
BS_:
BU_: A B
BO_ 1 ODD: 8 A
 SG_ Nibble : 0|4@1+ (1,0) [0|15] "" B
 SG_ Wide : 4|12@1- (0.5,-3) [-1027|1020.5] "" B
 SG_ SignedByte : 16|8@1- (1,0) [-128|127] "" B
 SG_ Tail : 24|32@1+ (0.01,0) [0|42949672.95] "" B
"""


def test_icd_messages_use_struct_and_other_layouts_fall_back_to_shifts() -> None:
    from edc_bench.protocol.layout import compile_message

    icd = default_icd()
    assert icd.bench_cmd.struct_format == "<BBBhHx"
    assert icd.rig_feedback.struct_format == "<BBBHhx"
    message = cantools.database.load_string(_UNALIGNED_DBC, "dbc").get_message_by_name("ODD")
    layout = compile_message(message)
    assert layout.struct_format is None

    @settings(max_examples=200, deadline=None)
    @given(_values(message))
    def check(values: dict[str, float]) -> None:
        ours = layout.encode(*(values[n] for n in layout.signal_names))
        assert ours == message.encode(values, scaling=True, strict=True)
        reference = message.decode(ours, decode_choices=False)
        for key, value in zip(layout.signal_names, layout.decode(ours), strict=True):
            assert value == pytest.approx(reference[key], abs=1e-9), key

    check()


@settings(max_examples=500, deadline=None)
@given(st.integers(0, 255), st.binary(min_size=0, max_size=8))
def test_e2e_crc_equals_the_crc_over_data_id_and_bytes_1_to_7(data_id: int, payload: bytes) -> None:
    from edc_bench.protocol.crc import e2e_crc

    assert e2e_crc(data_id, payload) == crc8_sae_j1850(bytes([data_id]) + payload[1:8])
