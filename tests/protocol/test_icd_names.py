"""Typed frames are filled from the DBC by signal name, and a DBC that disagrees is refused by name."""

from __future__ import annotations

from pathlib import Path

import pytest

from edc_bench.protocol import Icd, ProtocolError, dbc_path


def _edited_dbc(tmp_path: Path, old: str, new: str) -> Path:
    text = dbc_path().read_text(encoding="utf-8")
    assert old in text
    path = tmp_path / "icd.dbc"
    path.write_text(text.replace(old, new), encoding="utf-8")
    return path


def test_a_renamed_signal_is_refused_naming_it(tmp_path: Path) -> None:
    with pytest.raises(ProtocolError, match="lacks signal.*RackPosition"):
        Icd(_edited_dbc(tmp_path, " SG_ RackPosition ", " SG_ RackPos "))


def test_feedback_fields_come_from_their_signals(icd: Icd) -> None:
    payload = icd.make_rig_feedback(42, amp_enabled=True, watchdog_tripped=False, over_current=True,
                                    lvdt_fault=False, travel_limit=False, position_mm=12.345, current_a=-0.5)
    decoded = icd.database.decode_message("RIG_FEEDBACK", payload)  # cantools, by name
    reply = icd.parse_rig_feedback(payload)
    assert reply.counter == decoded["Counter"] == 42
    assert reply.position_mm == pytest.approx(decoded["RackPosition"]) and reply.current_a == pytest.approx(-0.5)
    assert (reply.amp_enabled, reply.over_current, reply.watchdog_tripped) == (True, True, False)
