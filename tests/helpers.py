"""Plain helpers shared by the test modules: ``from helpers import ...`` (``pythonpath = ["tests"]``, pyproject.toml)."""

from __future__ import annotations

import subprocess
import sys
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from edc_bench.testing.new_pump_type import write_new_pump_type  # noqa: F401  (the tests import it from here)

REPO = Path(__file__).resolve().parent.parent  # the repository's root (configs/, docs/, ...)


def edc_bench(*args: str, cwd: Path | None = None, timeout: float = 600,
              env: Mapping[str, str] | None = None) -> subprocess.CompletedProcess:
    """Run ``edc-bench ARGS`` (``python -m edc_bench``) in a subprocess; output captured as text."""
    return subprocess.run([sys.executable, "-m", "edc_bench", *args], capture_output=True, text=True, cwd=cwd,
                          timeout=timeout, env=env)


def run_cli(argv: list[str], capsys: Any) -> tuple[int, str, str]:
    """``edc-bench ARGV`` in this process: (exit code, stdout, stderr) with pytest's ``capsys``; argparse's exits
    become codes too."""
    from edc_bench.cli import main

    try:
        code = main(argv)
    except SystemExit as exc:
        code = exc.code if isinstance(exc.code, int) else 1
    out, err = capsys.readouterr()
    return code, out, err


def check_safe_and_complete(result: Any, rig: Any, tmp_path: Path) -> None:
    """A test that ended in a fault: INVALID, the rig at 0 V and READY or FAULT, SAFE commanded within 20 ms of
    the detection (when the bus still sends), and the record on disk holding every tick and frame up to it.

    ``result`` is a :class:`~edc_bench.bench.BenchResult`, ``rig`` the :class:`~edc_bench.sim.rig.SimulatedRig`
    (advanced 25 ms past the bench's last word, so its watchdog has acted where the bus is gone).
    """
    import json

    import can

    from edc_bench.protocol import BENCH_CMD_ID, Mode, default_icd
    from edc_bench.records.reader import load_trace
    from edc_bench.records.record import write_record
    from edc_bench.verdict.verdicts import Verdict

    outcome = result.outcome
    assert result.verdict == Verdict.INVALID
    assert result.classification is None
    from edc_bench.engine.outcome import AbortKind

    assert outcome.abort_time_s is not None or outcome.abort.kind is AbortKind.BUS_ERROR
    # the rig's amplifier is off: by SAFE or by its own watchdog
    assert rig.plant.drive_v == 0.0
    assert rig.firmware.state.name in ("READY", "FAULT")
    # SAFE commanded within 20 ms of detection, when the bus still sends
    if outcome.abort_time_s is not None:
        detected = outcome.ticks_start_s + outcome.abort_time_s
        icd, frames = default_icd(), result.frames
        safe_times = [frames.t_s[k] for k in range(frames.count)
                      if not frames.rx[k] and frames.can_id[k] == BENCH_CMD_ID and frames.t_s[k] >= detected
                      and icd.bench_cmd.decode(bytes(frames.data[k]))[2] == Mode.SAFE]
        if safe_times:
            assert safe_times[0] - detected <= 0.020
    # everything measured so far is on disk
    folder = write_record(result, tmp_path, figure=False)
    doc = json.loads((folder / "record.json").read_text())
    assert doc["verdict"] == Verdict.INVALID and doc["loop"]["abort_reason"] == outcome.abort_reason
    # the abort as a value beside its sentence, and the trust rule's problem, as the record keeps them
    assert doc["loop"]["abort"] == outcome.abort.as_dict() and "aborted" in doc["problems"]
    assert len(list(can.LogReader(str(folder / "can.log")))) == result.frames.count
    trace = load_trace(folder)
    assert len(trace["t_s"]) == outcome.ticks_run > 1000
    if outcome.abort_time_s is not None:  # the last tick recorded is the one that decided, or the one before it
        period_s = result.variant.controller.period_s
        assert outcome.abort_time_s - period_s - 1e-9 <= trace["t_s"][-1] <= outcome.abort_time_s + 1e-9


def rewrite_record_json(folder: Path, doc: dict[str, Any]) -> None:
    """Write ``doc`` as ``folder``'s record.json with its integrity manifest made anew: a record written so by a
    writer (another tool, another version), for tests of what readers make of its content; a record edited by hand
    keeps its old manifest and is refused as changed (tests/records/test_integrity.py)."""
    import json

    from edc_bench.records.integrity import manifest

    if "integrity" in doc:
        files = list(doc["integrity"]["files"])
        doc = {key: value for key, value in doc.items() if key != "integrity"}
        doc["integrity"] = manifest(doc, folder, files)
    (folder / "record.json").write_text(json.dumps(doc), encoding="utf-8")


class _LoopSamples:
    """Stands in for the batch path's sensors: what a loop's rig sent, in the order the batch asks for it."""

    def __init__(self, start_mm: float, position_mm: Any, current_a: Any) -> None:
        self._positions = iter([start_mm, *position_mm.tolist()])  # the SAFE reply's, then each tick's
        self._currents = iter(current_a[1:].tolist())  # each tick's from the first under the test's drive
        self.noise = None

    def sample(self) -> Any:
        import numpy as np

        return np.array([next(self._positions)])

    def current(self) -> Any:
        import numpy as np

        return np.array([next(self._currents)])


class _DrivesKept:
    """Stands in for the batch path's plant: keeps the drives the batch sends it."""

    def __init__(self) -> None:
        self.params = self.valve_params = [None]
        self.drives: list[float] = []

    def advance_period(self, drive_v: Any) -> None:
        self.drives.append(float(drive_v[0]))

    def add_heat(self, dt_s: float) -> None:
        pass


def batch_drives_from_loop(variant: Any, trace: Mapping[str, Any], seed: int) -> Any:
    """The drives the batch path sends when fed a loop test's samples (``trace``: its columns as arrays) in place of
    its own plant's: the batch's controller, reference, coil estimate and estimator, tick by tick."""
    import numpy as np

    from edc_bench.control.design import ControllerDesign
    from edc_bench.population import batch

    plant = _DrivesKept()
    samples = _LoopSamples(float(trace["reference_mm"][0]), trace["position_mm"], trace["current_a"])  # r(0): start
    run = batch._prepared(variant, ControllerDesign.from_variant(variant), plant, samples, [seed], None, None)
    run.all_ticks(run.feeder.setup)
    return np.array(plant.drives)
