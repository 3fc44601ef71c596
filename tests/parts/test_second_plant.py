"""The part diagnosis on a second, independent simulated plant and sensor (tests/parts/second_plant.py).

The pump type is brought up as a shop would: a station variant ``p-edc-second`` (p-edc-default under another name),
calibrated on five new valves of the second plant; then every case of :data:`second_plant.CASES` runs five tests
against that baseline. ``python -m tests.parts.second_plant`` prints the same cases as a table.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from edc_bench.config import load_variant
from edc_bench.verdict.baseline import load_baseline
from parts.second_plant import CASES, VARIANT_NAME, calibrate, case_failures, run_all, table, write_variant, \
    wrong_readings


@pytest.mark.slow
def test_the_part_diagnosis_names_the_part_at_fault_on_a_second_plant(monkeypatch: pytest.MonkeyPatch,
                                                                       tmp_path: Path) -> None:
    folder = tmp_path / "variants"
    monkeypatch.setenv("EDC_BENCH_VARIANTS_DIR", str(folder))
    write_variant(folder)
    baseline, path = calibrate(load_variant(VARIANT_NAME))
    assert baseline.tests == 5, "every calibration test converged"
    variant = load_variant(VARIANT_NAME)
    judged_against = load_baseline(variant)
    assert judged_against.calibrated and Path(judged_against.path) == path

    results = run_all(variant, CASES)

    assert [len(r.readings) for r in results] == [case.tests for case in CASES]
    failures = {r.case.name: case_failures(r) for r in results if case_failures(r)}
    assert not failures, f"\n{table(results)}\n\n{wrong_readings(results)}"
