"""The C firmware core behind the simulated rig: the same bench test, the same conformance as the prototype.

Skipped, saying how to build it, where the library is not built (CI builds it with gcc)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from edc_bench.bench import run_simulated_test
from edc_bench.config import load_variant
from edc_bench.errors import ConfigError
from edc_bench.physics.valve import parse_valve_spec
from edc_bench.rigcheck import run_rig_check
from edc_bench.runtime.bus import ClosingBus
from edc_bench.runtime.clock import SimulatedClock
from edc_bench.sim.inprocess import InProcessRig
from edc_bench.sim.lockstep_bus import lockstep_pair
from edc_bench.sim.rig import RigOptions, SimulatedRig
from firmware_proto.c_firmware import C_DIR, c_firmware_available, library_path
from realtime_judge import attempts, disturbance, figures

needs_library = pytest.mark.skipif(not c_firmware_available(), reason=f"the C firmware is not built "
                                   f"({library_path()}): this machine has no make or cc")


@needs_library
@pytest.mark.parametrize("valve", ["new", pytest.param("worn", marks=pytest.mark.slow)])  # worn: CI's slow pass
def test_a_bench_test_through_the_c_firmware_gives_the_python_firmwares_verdict_and_features(valve: str) -> None:
    variant = load_variant()
    python = run_simulated_test(variant, valve, 4, check_gains=False)
    c = run_simulated_test(variant, valve, 4, check_gains=False, firmware="c")
    assert c.simulation.firmware == "c" and python.simulation.firmware == "python"
    assert c.verdict == python.verdict
    for name in ("af", "a1"):
        assert c.parameters[name].value == pytest.approx(python.parameters[name].value, rel=1e-3), name


@needs_library
def test_rig_check_says_go_for_the_c_firmware() -> None:
    variant = load_variant()
    rig = SimulatedRig(variant, parse_valve_spec("new", variant), options=RigOptions(firmware="c"))
    bench_end, rig_end = lockstep_pair()
    with ClosingBus(bench_end) as bus, ClosingBus(rig_end):
        report = run_rig_check(bus, SimulatedClock(InProcessRig(rig_end, rig)), variant, commands=400)
    assert report.go, [(r.key, r.measured) for r in report.failed]


def test_without_the_library_the_rig_says_how_to_build_it(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    from firmware_proto import c_firmware

    monkeypatch.setenv(c_firmware.LIBRARY_ENV, str(tmp_path / "missing.so"))
    variant = load_variant()
    with pytest.raises(ConfigError, match=r"make -C .*firmware_proto/c"):
        SimulatedRig(variant, parse_valve_spec("new", variant), options=RigOptions(firmware="c"))


def test_the_c_firmware_builds_where_a_compiler_is() -> None:
    """tests/conftest.py builds it when make and cc are there: that build must not fail."""
    import os

    assert "EDC_BENCH_C_FIRMWARE_BUILD_ERROR" not in os.environ, os.environ.get("EDC_BENCH_C_FIRMWARE_BUILD_ERROR")


@pytest.mark.slow
def test_the_cortex_m_build_compiles_and_fits(tmp_path: Path) -> None:
    """The core with the reference board support (hal/, an STM32G431) cross-compiled with arm-none-eabi-gcc, no
    warnings; its flash and RAM use printed (CI installs the toolchain where it can)."""
    import shutil

    if not shutil.which("arm-none-eabi-gcc"):
        pytest.skip("arm-none-eabi-gcc is not installed (Debian: apt-get install gcc-arm-none-eabi "
                    "libnewlib-arm-none-eabi)")
    proc = subprocess.run(["make", "-C", str(C_DIR), "mcu", f"BUILD={tmp_path}", f"PYTHON={sys.executable}"],
                          capture_output=True, text=True)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "warning" not in (proc.stdout + proc.stderr).lower()
    # arm-none-eabi-size's line: text data bss dec hex filename
    line = next(line for line in proc.stdout.splitlines() if line.rstrip().endswith("rig.elf") and
                line.split()[0].isdigit())
    text, data, bss = (int(v) for v in line.split()[:3])
    print(f"Cortex-M4 build: flash {text + data} bytes, RAM {data + bss} bytes (static, without the stack)")
    assert text + data <= 128 * 1024 and data + bss <= 32 * 1024


@pytest.mark.slow
def test_the_c_build_has_no_warnings_at_wall_wextra(tmp_path: Path) -> None:
    """The host build from scratch (cantools generating the codec from the DBC), warnings as errors."""
    proc = subprocess.run(["make", "-C", str(C_DIR), f"BUILD={tmp_path}", f"PYTHON={sys.executable}"],
                          capture_output=True, text=True)
    if proc.returncode != 0 and "cc: not found" in proc.stderr + proc.stdout:
        pytest.skip("no C compiler on this machine")
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "warning" not in (proc.stdout + proc.stderr).lower()
    assert (tmp_path / "libedcrig.so").is_file()


@needs_library
@pytest.mark.slow
@pytest.mark.realtime
def test_a_real_time_test_over_the_rig_process_with_the_c_firmware_passes_a_new_valve(tmp_path: Path) -> None:
    """`edc-bench test --realtime --firmware c`: the rig process runs the C core; a new valve PASSes, as over the
    Python firmware. Up to three attempts; if every one the machine disturbed (tests/realtime_judge.py) did not
    PASS, the test is skipped with their figures."""
    import json

    def run():
        proc = subprocess.run([sys.executable, "-m", "edc_bench", "test", "--realtime", "--firmware", "c", "--valve",
                               "new", "--json", "--no-figure", "--no-history", "--out", "rec"], cwd=tmp_path,
                              capture_output=True, text=True, timeout=180)
        summary = json.loads(proc.stdout)
        doc = json.loads((tmp_path / summary["record_dir"] / "record.json").read_text())
        rig, loop = doc["simulation"]["rig_process"], doc["loop"]
        assert rig["firmware"] == "c"
        passed = proc.returncode == 0 and summary["verdict"] == "PASS"
        return (passed, f"{summary['verdict']} {summary['reasons']}, {figures(summary['timing'], rig)}",
                disturbance(summary["timing"], rig, (loop["ticks_lost"], loop["ticks_run"])))

    assert attempts(run, "C firmware, real time"), "an undisturbed real-time test over the C firmware did not PASS"
