"""A bench test's record folder, assembled from a :class:`BenchResult`.

Files are written data first (trace, CAN log), then the figure, then
``record.json`` which lists them: a folder whose record.json exists is
complete. A failure while drawing the figure never loses the data.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import TYPE_CHECKING, Any

from edc_bench.records.writer import (
    CAN_LOG_FILE,
    FIGURE_FILE,
    RECORD_FILE,
    RECORD_SCHEMA,
    TRACE_FILE,
    new_record_dir,
    write_can_log,
    write_json,
    write_trace,
)

if TYPE_CHECKING:
    from edc_bench.bench import BenchResult


def record_dict(result: BenchResult, files: dict[str, str | None]) -> dict[str, Any]:
    """The content of record.json."""
    from edc_bench.protocol import default_icd

    ident = result.identification
    outcome = dataclasses.asdict(result.outcome)
    return {
        "schema": RECORD_SCHEMA,
        "verdict": result.verdict,
        "reasons": result.reasons,
        "valve_id": result.valve_id,
        "identity": result.identity,
        "variant": result.variant.name,
        "part_number": result.variant.pump.part_number,
        "started_at": result.started_at,
        "clock": result.clock,
        "software_version": result.software_version,
        "firmware_version": result.outcome.fw_version,
        "icd_version": ".".join(str(v) for v in default_icd().version),
        "features": result.features,
        "classification": result.classification,
        "baseline": result.baseline,
        "parameters": result.parameters,
        "converged": result.converged,
        "identification": None if ident is None else {
            "estimator": result.variant.estimator.kind,
            "settle_s": ident.settle_s,
            "condition_number": ident.condition_number,
            "samples_in_last_window": ident.samples_used,
            "residual_rms_v": ident.residual_rms_v,
        },
        "timing": result.timing,
        "loop": outcome,
        "stability_margins": None if result.margins is None else dataclasses.asdict(result.margins),
        "truth": None if result.truth is None else result.truth._asdict(),
        "simulation": result.simulation,
        "config": result.variant.model_dump(mode="json"),
        "files": files,
    }


def write_record(result: BenchResult, out_dir: Path, figure: bool = True, folder: Path | None = None) -> Path:
    """Write the record folder of ``result`` under ``out_dir``.

    Parameters
    ----------
    result : BenchResult
        The test.
    out_dir : pathlib.Path
        Parent folder; a new subfolder is created per test.
    figure : bool
        Draw report.png (default).
    folder : pathlib.Path, optional
        An existing folder for this test (e.g. the one the CAN log was
        streamed into); a new one under ``out_dir`` otherwise.

    Returns
    -------
    pathlib.Path
        The record folder.
    """
    if folder is None:
        folder = new_record_dir(Path(out_dir), result.valve_id, result.variant.name, result.started_at)
    files: dict[str, str | None] = {"trace": None, "can_log": None, "figure": None}
    write_trace(folder / TRACE_FILE, result.trace)
    files["trace"] = TRACE_FILE
    write_can_log(folder / CAN_LOG_FILE, result.frames)
    files["can_log"] = CAN_LOG_FILE
    if figure and len(result.trace["t_s"]):
        from edc_bench.records.figure import draw_report_figure

        try:
            draw_report_figure(
                folder / FIGURE_FILE, result.trace,
                f"{result.variant.name} / valve {result.valve_id or '?'}: {result.verdict}",
                truth=None if result.truth is None else result.truth._asdict(),
                excitation_start_s=result.variant.excitation.move_s,
            )
            files["figure"] = FIGURE_FILE
        except Exception as exc:  # noqa: BLE001 - a figure is never worth losing the record
            files["figure_error"] = f"{type(exc).__name__}: {exc}"
    write_json(folder / RECORD_FILE, record_dict(result, files))
    return folder
