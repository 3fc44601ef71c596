"""`edc-bench tune --write`: the refused gains name it; it writes gains that pass, keeping the file's comments."""

from __future__ import annotations

import tomllib

import pytest
from helpers import edc_bench, write_new_pump_type

from edc_bench.cli.exit_codes import ExitCode
from edc_bench.config import load_variant
from edc_bench.runtime.gain_check import check_variant_gains


def _comments(text: str) -> list[str]:
    return [line[line.index("#"):] for line in text.splitlines() if "#" in line]


@pytest.mark.slow  # 10-16 s: the default suite stays under 5 minutes; CI's slow pass runs it
def test_refusal_names_tune_and_tune_write_fixes_the_gains(tmp_path) -> None:
    path = write_new_pump_type(tmp_path / "variants")
    before = path.read_text(encoding="utf-8")
    refused = edc_bench("test", "--variant", str(path), "--no-history", "--out", str(tmp_path / "records"),
                        cwd=tmp_path)
    assert refused.returncode == ExitCode.BAD_INPUT, refused.stderr
    assert f"'edc-bench tune --variant {path}' proposes gains" in refused.stderr
    assert "Traceback" not in refused.stderr

    shown = edc_bench("tune", "--variant", str(path), cwd=tmp_path)
    assert shown.returncode == 0, shown.stderr
    assert "proposed" in shown.stdout and path.read_text(encoding="utf-8") == before  # without --write: no change

    written = edc_bench("tune", "--variant", str(path), "--write", cwd=tmp_path)
    assert written.returncode == 0, written.stderr
    after = path.read_text(encoding="utf-8")
    assert _comments(after) == _comments(before)  # every comment kept, in place
    assert len(after.splitlines()) == len(before.splitlines())
    gains = tomllib.loads(after)["controller"]
    assert gains["kp_v_per_mm"] != tomllib.loads(before)["controller"]["kp_v_per_mm"]
    margins = check_variant_gains(load_variant(path))  # would raise if the margins were short
    assert margins.gain_margin_db >= 6.0 and margins.phase_margin_deg >= 30.0
    proposed = next(line for line in shown.stdout.splitlines() if line.startswith("proposed"))
    assert f"{gains['kp_v_per_mm']:.4g}" in proposed


@pytest.mark.slow  # seconds: CI's slow pass runs it (the default suite stays under 5 minutes on CI)
def test_tune_that_cannot_write_says_so_and_leaves_the_file_whole(tmp_path) -> None:
    path = write_new_pump_type(tmp_path / "variants")
    before = path.read_text(encoding="utf-8")
    (path.parent / f".{path.name}.tune").mkdir()  # where the new text would go: not writable, even for root
    result = edc_bench("tune", "--variant", str(path), "--write", cwd=tmp_path)
    assert result.returncode == ExitCode.BAD_INPUT
    assert "cannot write the gains" in result.stderr and "Traceback" not in result.stderr
    assert path.read_text(encoding="utf-8") == before
