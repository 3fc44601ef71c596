"""``edc-bench rig-selfcheck`` and the ledger: no reference valve (said once, exit 18), registering, GO, NO-GO
naming the drift (exit 17), every check in the history, ``history --rig`` showing them."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from helpers import run_cli

from edc_bench.cli.exit_codes import ExitCode
from edc_bench.history.store import HistoryStore


@pytest.mark.slow  # over 5 s each: the default suite's 5 minutes (CI's slow pass runs it)
def test_register_check_and_the_ledger(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                       capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.setenv("EDC_BENCH_DATA_DIR", str(tmp_path / "data"))
    monkeypatch.chdir(tmp_path)
    db = ["--db", f"sqlite:///{tmp_path / 'h.sqlite'}", "--station", "bench1"]

    code, out, err = run_cli(["rig-selfcheck", *db], capsys)
    assert code == ExitCode.NO_REFERENCE_VALVE == 18, err
    assert "no reference valve is registered for station 'bench1'" in err
    assert "edc-bench rig-selfcheck --register --valve-id ID" in err and not out

    code, out, err = run_cli(["rig-selfcheck", "--register", "--valve-id", "REF-1", "--by", "ana", *db], capsys)
    assert code == 0, err
    assert out.startswith("registered reference valve REF-1 for station bench1 (variant p-edc-default): LVDT zero "
                          "0.005 mm"), out

    code, out, err = run_cli(["rig-selfcheck", *db], capsys)  # another seed than the registration's
    assert code == 0, out + err
    assert out.splitlines()[0] == "rig self-check: GO"

    code, out, err = run_cli(["rig-selfcheck", "--rig-drift", "lvdt_offset_mm=0.05", "--json", "--by", "Bea Otto",
                              *db], capsys)
    assert code == ExitCode.RIG_DRIFTED == 17, err
    summary = json.loads(out)
    assert summary["verdict"] == "NO-GO" and summary["causes"] == ["LVDT zero"]
    assert summary["line"].startswith("rig self-check: NO-GO: LVDT zero moved +0.050 mm (limit 0.02 mm)")
    assert [name for name, f in summary["figures"].items() if f["out"]] == ["lvdt_zero_mm"]
    assert summary["drift"] == "lvdt_offset_mm=0.05" and summary["seed"] == 2  # one more than the last check's

    with HistoryStore(db[1]) as store:
        checks = store.rig_checks("bench1")
        assert [(c.verdict, c.causes, c.checked_by) for c in checks] == [
            ("GO", "", checks[0].checked_by), ("NO-GO", "LVDT zero", "Bea Otto")]
        assert checks[1].lvdt_zero_mm == pytest.approx(0.055, abs=0.001) and checks[1].simulated
        assert store.reference("bench1").registered_by == "ana"

    code, out, err = run_cli(["history", "--rig", "--db", db[1]], capsys)
    assert code == 0, err
    out = " ".join(out.split())  # the title wraps
    assert "station bench1: reference valve REF-1 (p-edc-default)" in out and "2 check(s), 1 NO-GO" in out
    assert "+0.050" in out and "LVDT zero" in out
    assert "Bea Otto" in out  # who ran each check: the operator, not the PC's login (#53)
    code, out, err = run_cli(["history", "--rig", "--station", "bench1", "--json", "--db", db[1]], capsys)
    ledger = json.loads(out)
    assert [c["verdict"] for c in ledger[0]["checks"]] == ["GO", "NO-GO"]
    assert ledger[0]["checks"][1]["drift"]["lvdt_zero_mm"] == pytest.approx(0.05, abs=0.001)
    # the registration as the ledger's JSON has always given it: its figures beside who and when
    assert list(ledger[0]["reference"]) == ["id", "station", "valve_id", "variant", "registered_at", "registered_by",
                                            "simulated", "lvdt_zero_mm", "current_zero_a", "coil_r20_ohm",
                                            "a0_v_per_mm", "af_v", "a1_v_s_per_mm"]
    assert ledger[0]["reference"]["valve_id"] == "REF-1" and ledger[0]["reference"]["af_v"] > 0
    code, _, err = run_cli(["history", "--rig", "--station", "bench9", "--db", db[1]], capsys)
    assert code == 2 and "no reference valve is registered of station 'bench9'" in err

    # a registration again replaces the earlier one by a new row; the ledger keeps both
    code, out, err = run_cli(["rig-selfcheck", "--register", "--valve-id", "REF-2", *db], capsys)
    assert code == 0 and "it replaces the registration of" in out and "(valve REF-1)" in out, out + err
    with HistoryStore(db[1]) as store:
        assert store.reference("bench1").valve_id == "REF-2" and len(store.references("bench1")) == 2
