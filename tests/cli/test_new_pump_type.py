"""docs/new-pump-type.md, run as written against the simulated rig with a pump type unlike the shipped ones."""

from __future__ import annotations

import json
import os
import tomllib

import pytest
from helpers import edc_bench, write_new_pump_type

from edc_bench.cli.exit_codes import ExitCode


@pytest.mark.slow  # ten commands, seven simulated 30 s tests (about a minute)
def test_bringing_up_a_new_pump_type(tmp_path) -> None:
    variants = tmp_path / "variants"
    env = {**os.environ, "EDC_BENCH_VARIANTS_DIR": str(variants)}
    write_new_pump_type(variants)
    records = str(tmp_path / "records")

    def run(*args: str):
        return edc_bench(*args, cwd=tmp_path, env=env)

    def test(*args: str) -> dict:
        result = run("test", "--variant", "PE-EDC-9001", "--no-history", "--no-figure", "--json", "--out", records,
                     *args)
        assert "Traceback" not in result.stderr
        return {"code": result.returncode, **(json.loads(result.stdout) if result.stdout else {}),
                "stderr": result.stderr}

    # 2. check it
    listed = run("variants")
    assert "p-edc-newtype" in listed.stdout and "PE-EDC-9001" in listed.stdout

    # 3. the default's gains are refused, naming tune; tune --write fixes them
    refused = test()
    assert refused["code"] == ExitCode.BAD_INPUT and "'edc-bench tune --variant p-edc-newtype'" in refused["stderr"]
    tuned = run("tune", "--variant", "p-edc-newtype", "--write")
    assert tuned.returncode == 0, tuned.stderr
    proposed = next(line for line in tuned.stdout.splitlines() if line.startswith("proposed")).split()
    gm_db, pm_deg = float(proposed[5]), float(proposed[6])
    assert gm_db >= 6.0 and pm_deg >= 30.0
    print(f"tuned: {' '.join(proposed)}")

    # 4. before calibration: no verdict, the exact calibrate command instead
    before = test()
    assert before["code"] == ExitCode.INVALID and before["converged"]
    command = "edc-bench calibrate --variant p-edc-newtype --valve new --append"
    assert f"'{command}'" in before["reasons"][0]
    for n in range(5):  # five runs, as a technician calibrates five valves
        calibrated = run(*command.split()[1:], "--valve-id", f"N-{n + 1:04d}", "--out", records)
        assert calibrated.returncode == 0, calibrated.stderr
    baseline = tomllib.loads((variants / "baselines" / "p-edc-newtype.toml").read_text(encoding="utf-8"))
    assert baseline["tests"] == 5 and len(list((variants / "baselines" / "earlier").iterdir())) == 4
    truth = before["truth"]
    af_error, a1_error = baseline["af_v"] / truth["af"] - 1, baseline["a1_v_s_per_mm"] / truth["a1"] - 1
    af_u, a1_u = baseline["af_uncertainty_v"] / baseline["af_v"], baseline["a1_uncertainty_v_s_per_mm"] / \
        baseline["a1_v_s_per_mm"]
    print(f"baseline against the plant's truth: af {af_error:+.2%}, a1 {a1_error:+.2%}; "
          f"stated uncertainty af {af_u:.2%}, a1 {a1_u:.2%}")
    assert abs(af_error) < 0.02 and abs(a1_error) < 0.02
    assert 0 < af_u < 0.02 and 0 < a1_u < 0.02

    # 5. after calibration: a new valve passes, a worn one fails, both converged within the test
    new, worn = test("--valve", "new"), test("--valve", "worn")
    for name, result in (("new", new), ("worn", worn)):
        print(f"{name}: {result['verdict']}, features x{result['classification']['features_rel']['af']:.2f} / "
              f"x{result['classification']['features_rel']['a1']:.2f}, settle {result['settle_s']}")
        assert result["converged"] and max(result["settle_s"]["af"], result["settle_s"]["a1"]) < 10.0
    assert new["code"] == ExitCode.OK and new["verdict"] == "PASS"
    assert worn["code"] == ExitCode.FAIL and worn["verdict"] == "FAIL"
