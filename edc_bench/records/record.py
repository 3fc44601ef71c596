"""The record of a bench test: everything it produced, and its folder.

:class:`BenchResult` is the record in memory (like OpenHTF's test record):
what the loop measured, the judgement and who ran it. Its folder is written
data first (trace, CAN log), then the figure, then ``record.json`` which
lists them: a folder whose record.json exists is complete. A failure while
drawing the figure never loses the data. record.json holds everything the
report shows (reference values, the model that judged and its decision
plane), so the report reads the folder alone.
"""

from __future__ import annotations

import errno

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from edc_bench import __version__
from edc_bench.config.models import Variant
from edc_bench.engine.outcome import LoopOutcome
from edc_bench.engine.tick_timing import TickTiming
from edc_bench.engine.trace import CanFrameLog
from edc_bench.identification.analysis import Identification
from edc_bench.physics.feedforward import FeedforwardParameters
from edc_bench.protocol import default_icd
from edc_bench.records.mdf import write_trace_mf4
from edc_bench.records.writer import (
    CAN_LOG_FILE,
    FIGURE_FILE,
    RECORD_FILE,
    RECORD_SCHEMA,
    TRACE_FILE,
    json_safe,
    new_record_dir,
    write_can_log,
    write_json,
)
from edc_bench.records.integrity import manifest
from edc_bench.records.advice import Advice, Cause, advice, invalid_cause
from edc_bench.records.schema import (
    BaselineSummary,
    ClassificationSummary,
    EscalationSummary,
    IdentificationSummary,
    Identity,
    LoopSummary,
    ParameterEstimate,
    Record,
    RecordFiles,
    RetestSummary,
    SimulationSummary,
    StabilityMargins,
    StopSummary,
)
from edc_bench.section import FeaturePair
from edc_bench.verdict.judgement import Judgement
from edc_bench.verdict.verdicts import Verdict


@dataclass(frozen=True)
class BenchResult:
    """Everything one bench test produced.

    Attributes
    ----------
    judgement : Judgement
        The verdict, its reasons, the identified parameters and features,
        and what they were compared with (see also the shortcuts below).
    timing : TickTiming
        Tick lateness percentiles, ticks late, missed replies, CPU steal.
    outcome : LoopOutcome
        What happened in the loop (aborts, replies, heartbeats).
    margins : StabilityMargins or None
        The gain check's margins (None if it was skipped), as the record keeps them.
    variant : Variant
        The variant as the test ran it.
    valve_id, started_at, clock : str
        The valve's id, the UTC start time, ``simulated`` or ``real-time``.
    test_id : str
        The test's own id (a random UUID, hex), made at its start: record.json carries it, and the history knows
        the test by it (not by its folder's path, which copies change).
    trace : dict of numpy.ndarray
        Per-tick columns.
    frames : CanFrameLog
        Every frame sent and received.
    truth : FeedforwardParameters or None
        The simulated plant's true parameters (simulated rig only).
    simulation : SimulationSummary or None
        The simulated valve and rig, when the rig was simulated.
    can_log_path : pathlib.Path or None
        Where the CAN log was streamed while the test ran, if it was.
    stop : StopSummary or None
        Why and when the test ended: ``reason`` (a :class:`~edc_bench.engine.outcome.StopReason`), ``time_s``,
        ``full_length`` (the fixed length was asked for), ``max_s``, and an early stop's figures.
    identity : Identity
        Who and where: the pump's serial, the station, the operator, the workshop, the job.

    Built once, complete, by :func:`edc_bench.bench.run_bench_test`; :func:`write_record` writes it as it is.
    """

    judgement: Judgement
    timing: TickTiming
    outcome: LoopOutcome
    margins: StabilityMargins | None
    variant: Variant
    valve_id: str
    started_at: str
    clock: str
    trace: dict[str, np.ndarray]
    frames: CanFrameLog
    truth: FeedforwardParameters | None = None
    simulation: SimulationSummary | None = None
    can_log_path: Path | None = None
    stop: StopSummary | None = None
    software_version: str = __version__
    identity: Identity = Identity()
    test_id: str = ""

    @property
    def verdict(self) -> Verdict:
        """PASS, MARGINAL, FAIL, INVALID (see ``reasons``) or UNCLASSIFIED."""
        return self.judgement.verdict

    @property
    def reasons(self) -> list[str]:
        """Why the verdict is what it is."""
        return self.judgement.reasons

    @property
    def advice(self) -> Advice:
        """What the technician does next (:func:`~edc_bench.records.advice.advice`)."""
        abort = self.outcome.abort
        return advice(self.verdict, self.judgement.problems, abort.kind if abort is not None else None,
                      self.judgement.part)

    @property
    def invalid_cause(self) -> Cause:
        """Who the test points at if INVALID (:func:`~edc_bench.records.advice.invalid_cause`)."""
        abort = self.outcome.abort
        return invalid_cause(self.judgement.problems, abort.kind if abort is not None else None)

    @property
    def parameters(self) -> dict[str, ParameterEstimate]:
        """a3, a2, a1, a0, b, af as identified (value, standard error, estimated or fixed)."""
        return self.judgement.parameters

    @property
    def features(self) -> FeaturePair:
        """af and a1, the diagnosis inputs (V, V s/mm; NaN where not identified)."""
        return self.judgement.features

    @property
    def converged(self) -> bool:
        """af and a1 settled and stayed settled."""
        return self.judgement.converged

    @property
    def identification(self) -> Identification | None:
        """Settle times, conditioning and uncertainty of the identification."""
        return self.judgement.identification

    @property
    def classification(self) -> ClassificationSummary | None:
        """The classifier's judgement (None if it was not asked)."""
        return self.judgement.classification

    @property
    def baseline(self) -> BaselineSummary | None:
        """The baseline the features were compared with (None if not classified)."""
        return self.judgement.baseline


def build_record(result: BenchResult, files: RecordFiles, retest: RetestSummary | None = None,
                 escalation: EscalationSummary | None = None, notes: Sequence[str] = ()) -> Record:
    """The record of ``result`` as the one model every reader reads (:class:`~.schema.Record`), built once:
    record.json is its serialisation (:func:`record_json`).

    Parameters
    ----------
    result : BenchResult
        The test.
    files : RecordFiles
        The folder's files as written (None: not written, with ``<name>_error`` saying why).
    retest : RetestSummary, optional
        This test repeats a MARGINAL: the first test and what the two decide.
    escalation : EscalationSummary, optional
        The same valve INVALID twice (:mod:`~edc_bench.records.escalation_link`).
    notes : sequence of str, optional
        What happened after the test that the record should say, after the loop's own events.

    Raises
    ------
    pydantic.ValidationError
        If a section does not fit its model (a bug in the code that made it: the record is not written wrong).
    """
    judgement = result.judgement
    ident = result.identification
    loop = LoopSummary.of(result.outcome)
    if notes:
        loop = loop.model_copy(update={"events": [*loop.events, *notes]})
    return Record(
        schema=RECORD_SCHEMA,
        verdict=result.verdict,
        reasons=list(result.reasons),
        problems=judgement.problems.names,
        valve_id=result.valve_id,
        identity=Identity.model_validate(result.identity),
        variant=result.variant.name,
        part_number=result.variant.pump.part_number,
        started_at=result.started_at,
        test_id=result.test_id,
        clock=result.clock,
        software_version=result.software_version,
        firmware_version=result.outcome.fw_version,
        icd_version=".".join(str(v) for v in default_icd().version),
        features=result.features,
        features_volt=judgement.features_volt,
        coil=judgement.coil,
        classification=judgement.classification,
        baseline=judgement.baseline,
        reference_values=judgement.reference_values,
        decision_plane=judgement.decision_plane,
        part=judgement.part,
        parameters=judgement.parameters,
        converged=result.converged,
        identification=None if ident is None else IdentificationSummary(
            estimator=result.variant.estimator.kind,
            excitation_start_s=result.variant.excitation.move_s,
            method="least squares over whole excitation periods, on the smoothed rack trajectory",
            periods=ident.periods,
            periods_estimated=ident.periods_estimated,
            period_s=ident.period_s,
            settled=ident.settled,
            samples_used=ident.samples_used,
            condition_number=ident.condition_number,
            residual_rms_v=ident.residual_rms_v,
            model_fit=None if ident.model_fit is None else ident.model_fit.summary(),
            gain_terms=ident.nuisance,
            online_settle_s=ident.settle_s,
        ),
        stop=result.stop,
        timing=result.timing,
        loop=loop,
        stability_margins=result.margins,
        truth=None if result.truth is None else result.truth._asdict(),
        simulation=result.simulation,
        config=result.variant.model_dump(mode="json"),
        retest=retest,
        escalation=escalation,
        files=files,
    )


def record_json(record: Record) -> dict[str, Any]:
    """record.json's content: ``record`` serialised (every field it declares, ``schema`` by that name; the fields
    only read, never written, left out), its ``integrity`` section aside (added over this content)."""
    return json_safe(record.model_dump(mode="json", by_alias=True, exclude={"integrity"}))


def write_record(result: BenchResult, out_dir: Path, figure: bool = True, folder: Path | None = None,
                 notes: Sequence[str] = (), retest: RetestSummary | None = None) -> Path:
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
    notes : sequence of str, optional
        What happened after the test that the record should say (a bus that failed to close, a first folder
        that could not be written), added to the loop's events in record.json; ``result`` is not changed.
    retest : RetestSummary, optional
        This test repeats a MARGINAL: the first test's folder and verdict and what the two decide
        (:meth:`~edc_bench.verdict.retest.Decision.record_entry`).

    Each file is written on its own: one that cannot be written (a full disk) is named with its error in
    record.json's ``files`` (``trace_error``, ``can_log_error``, ``figure_error``), and record.json, the
    smallest, is still written last.

    An INVALID test of a valve whose last test here was INVALID too, both times for a cause the valve itself can
    cause, is written with its ``escalation`` (:mod:`~edc_bench.records.escalation_link`): every front end that
    writes a record says it, and reads it back from the record.

    Returns
    -------
    pathlib.Path
        The record folder.

    Raises
    ------
    OSError
        If the folder or record.json cannot be written.
    pydantic.ValidationError
        If a section does not fit the record's model (a bug in the code that made it): record.json is not written,
        the data files already written are kept.
    """
    if folder is None:
        folder = new_record_dir(Path(out_dir), result.valve_id, result.variant.name, result.started_at)
    trace = can_log = drawn = None
    no_room = False
    errors: dict[str, str] = {}  # RecordFiles's <name>_error: why a file could not be written
    try:
        write_trace_mf4(folder / TRACE_FILE, result.trace, result.frames, ticks_start_s=result.outcome.ticks_start_s,
                        origin_unix_s=result.frames.origin_unix_s,
                        comment=f"edc-bench {result.variant.name}, valve {result.valve_id or '?'}: {result.verdict}")
        trace = TRACE_FILE
    except OSError as exc:
        errors.update(trace_error=f"{type(exc).__name__}: {exc}")
    try:
        if result.can_log_path != folder / CAN_LOG_FILE:  # streamed there while the test ran: complete already
            write_can_log(folder / CAN_LOG_FILE, result.frames)
        can_log = CAN_LOG_FILE
    except OSError as exc:
        errors.update(can_log_error=f"{type(exc).__name__}: {exc}")
    if figure and len(result.trace["t_s"]):
        from edc_bench.records.figure import draw_report_figure

        try:
            draw_report_figure(
                folder / FIGURE_FILE, result.trace,
                f"{result.variant.name} / valve {result.valve_id or '?'}: {result.verdict}",
                truth=None if result.truth is None else result.truth._asdict(),
                excitation_start_s=result.variant.excitation.move_s,
            )
            drawn = FIGURE_FILE
        except Exception as exc:  # noqa: BLE001 - a figure is never worth losing the record
            errors.update(figure_error=f"{type(exc).__name__}: {exc}")
            no_room = isinstance(exc, OSError) and exc.errno in (errno.ENOSPC, errno.EDQUOT)
    from edc_bench.records.escalation_link import find_escalation

    escalated = find_escalation(folder, result.valve_id, result.variant.name, result.started_at, str(result.verdict),
                                result.invalid_cause)
    files = RecordFiles(trace=trace, can_log=can_log, figure=drawn, figure_no_room=no_room or None, **errors)
    record = build_record(result, files, retest, escalated, notes)
    doc = record_json(record)
    # what the test wrote, as it wrote it: every reader checks it (records.integrity)
    doc["integrity"] = manifest(doc, folder, [name for name in (trace, can_log, drawn) if name])
    write_json(folder / RECORD_FILE, doc)
    return folder


def missing_files(folder: Path) -> dict[str, str]:
    """The files a written record could not hold, with why (record.json's ``files``, the figure aside)."""
    from edc_bench.records.reader import load_record

    return load_record(folder).files.missing()
