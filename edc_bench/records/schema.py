"""record.json as typed values: the one form in which the report, the history, replay and classify read a record.

:func:`edc_bench.records.reader.load_record` parses a record folder's
record.json into a :class:`Record` (an older schema brought to today's form
first), so no reader looks a figure up by a string key or guards against a
section that is missing or of the wrong type: a record that does not fit
is refused once, with the field and what is wrong with it.

The writer builds the same model (:func:`edc_bench.records.record.build_record`, once, from the test's
result) and record.json is its serialisation: one shape to build, write and read, so a field declared here is
written, read back and covered by the record's integrity manifest without another file edited (a field only
read, never written, is declared ``exclude=True``: ``retested_by``). Older schemas are brought to today's form
in one place on read (:func:`edc_bench.records.reader.upgraded`).

A part made below the records is declared where it is made and assembled here, so the code that makes it builds
the model record.json holds (no dict in between): the coil's finding in
:mod:`edc_bench.identification.sections` (with the model fit), the verdict's parts (parameters, reference values, classification,
baseline, decision plane) in :mod:`edc_bench.verdict.sections`, the tick timing in
:mod:`edc_bench.engine.tick_timing`.

Every section accepts keys it does not know (``extra="allow"``): a record a newer edc-bench wrote is still read
by this one. The variant as run (``config``) is kept as the mapping it was written as: it is read back through
the variant's own models (replay's :func:`edc_bench.config.parse_variant`, which says what an older variant
lacks), not declared a second time here. The simulated rig's section is in :mod:`edc_bench.records.simulation`.
"""

from __future__ import annotations

from typing import Annotated, Any

from pydantic import BaseModel, BeforeValidator, ConfigDict, Field

from edc_bench.engine.loop_summary import LoopSummary
from edc_bench.engine.outcome import StopReason
from edc_bench.engine.problems import Problem
from edc_bench.engine.tick_timing import TickTiming
from edc_bench.identification.sections import CoilFinding, ModelFitSummary
from edc_bench.records.advice import Advice, Area, Cause, advice, invalid_area, invalid_cause
from edc_bench.records.simulation import SimulationSummary
from edc_bench.runtime.clock_kind import ClockKind
from edc_bench.section import FeaturePair, Section
from edc_bench.verdict.sections import (
    BaselineSummary,
    ClassificationSummary,
    DecisionPlane,
    ParameterEstimate,
    MaybeVerdict,
    ReferenceValue,
    RetestSummary,
    none_if_empty,
)
from edc_bench.verdict.part_sections import VALVE_ONLY, PartDiagnosis
from edc_bench.verdict.verdicts import Verdict


def _none_if_no_rig(value: Any) -> Any:
    return None if value == {} else value  # an empty section names no simulated rig


class Identity(Section):
    """Who and where: the pump's serial, the station, the operator."""

    pump_serial: str = ""
    station: str = ""
    # the station's name for the customer's page (--station, else [station] shown_name, else name): "" when the shop named
    # it nowhere (then the page prints no station: never the PC's host name); None in older records (the page then
    # prints ``station`` as it did)
    station_shown: str | None = None
    operator: str = ""
    shop: str = ""  # the workshop ([station] shop in station.toml): the customer's page prints it
    shop_address: str = ""
    job_ref: str = ""  # the job or vehicle reference scanned with the valve ('' if none): the customer's page prints it
    purpose: str = ""  # "calibration" for a baseline's test (edc-bench calibrate), '' for a valve's


class IdentificationSummary(Section):
    """The period fit's figures: periods used, conditioning, residual, model fit; the online settle times."""

    estimator: str = ""
    excitation_start_s: float | None = None
    method: str = ""
    periods: int = 0
    periods_estimated: int | None = None  # periods with rows enough for their own estimate (None: older record)
    period_s: float | None = None
    settled: bool | None = None
    samples_used: int | None = None
    condition_number: float | None = None
    residual_rms_v: float | None = None
    model_fit: ModelFitSummary | None = None
    gain_terms: dict[str, float | None] | None = None
    online_settle_s: dict[str, float | None] | None = None


class StopSummary(Section):
    """Why and when the test ended, and the longest it could have run."""

    # a StopReason; a str only for a reason this edc-bench does not know (left_to_right: a known reason read from
    # JSON is the enum, not the plain str a smart union would pick)
    reason: StopReason | str = Field("", union_mode="left_to_right")
    time_s: float | None = None
    decided_s: float | None = None  # an early stop: when the loop took the decision (after time_s in real time)
    max_s: float | None = None
    full_length: bool = False
    early_stop: bool | None = None
    why_full_length: str | None = None
    periods: int | None = None
    verdict: Verdict | None = None
    features_rel: FeaturePair | None = None
    half_width_rel: FeaturePair | None = None
    misfit_half_width_rel: FeaturePair | None = None
    baseline_half_width_rel: FeaturePair | None = None
    residual_half_width_rel: FeaturePair | None = None
    confidence: float | None = None
    problems: list[str] = Field(default_factory=list)


class StabilityMargins(Section):
    """The gain check's margins of the feedback loop before the test (:func:`edc_bench.control.stability.loop_margins`;
    an infinite margin, which JSON cannot hold, reads as None)."""

    gain_margin_db: float | None = None
    phase_margin_deg: float | None = None
    crossover_hz: float | None = None
    closed_loop_stable: bool | None = None
    max_pole_radius: float | None = None
    delay_ticks: int = 1


class EscalationSummary(Section):
    """A second INVALID of the same valve, both times for a cause the valve itself can cause
    (:mod:`edc_bench.records.escalation_link`): it may be seized."""

    of_record: str = ""  # the earlier test's record folder (its name)
    of_verdict: MaybeVerdict = None  # the earlier test's verdict (INVALID)
    of_cause: Annotated[Cause | None, BeforeValidator(none_if_empty)] = None  # who the earlier test pointed at
    words: str = ""  # the technician's line (records.advice.SEIZED)


class RetestedBy(Section):
    """A first test's retest, found beside it when its report is drawn (never in its record.json: the first test
    was written before its retest ran)."""

    record: str = ""  # the retest's record folder (its name)
    verdict: MaybeVerdict = None  # the retest's verdict
    decision: MaybeVerdict = None  # what the pair decides
    words: str = ""  # the technician's line for the pair


class RecordFiles(Section):
    """The record folder's files (None: not written); ``<name>_error`` keys say why one could not be."""

    trace: str | None = None
    can_log: str | None = None
    figure: str | None = None
    #: the figure could not be written for want of room (a full disk or quota), not for a fault in its drawing
    figure_no_room: bool | None = None

    @property
    def figure_error(self) -> str | None:
        """Why the figure could not be drawn or written (None: drawn, or nothing to draw)."""
        error = (self.model_extra or {}).get("figure_error")
        return None if self.figure or error is None else str(error)

    def missing(self) -> dict[str, str]:
        """The data files the folder could not hold, with why (the figure aside: it is redrawn from the data)."""
        return {key[: -len("_error")]: str(value) for key, value in (self.model_extra or {}).items()
                if key.endswith("_error") and key != "figure_error"}


class Record(Section):
    """A bench test's record.json.

    Only ``verdict`` is required: a record cut short (or written before a
    section existed) reads with that section empty, and what it lacks is
    for each reader to say.
    """

    schema_version: int = Field(0, alias="schema")
    integrity: dict[str, Any] | None = None  # the digests of what the test wrote (records.integrity)
    verdict: Verdict
    reasons: list[str] = Field(default_factory=list)
    problems: list[str] = Field(default_factory=list)
    valve_id: str = ""
    identity: Identity = Identity()
    variant: str = ""
    part_number: str = ""
    started_at: str = ""
    test_id: str = ""  # the test's own id, made at its start (schema 8 on; '' in older records)
    clock: str = ""
    software_version: str = ""
    firmware_version: str | None = None
    icd_version: str = ""
    features: FeaturePair = FeaturePair()
    features_volt: FeaturePair = FeaturePair()
    coil: CoilFinding | None = None
    classification: ClassificationSummary | None = None
    baseline: BaselineSummary | None = None
    reference_values: dict[str, ReferenceValue] = Field(default_factory=dict)
    decision_plane: DecisionPlane | None = None
    parameters: dict[str, ParameterEstimate] = Field(default_factory=dict)
    converged: bool | None = None
    identification: IdentificationSummary | None = None
    stop: StopSummary | None = None
    timing: TickTiming = TickTiming()
    loop: LoopSummary = LoopSummary()
    stability_margins: StabilityMargins | None = None
    truth: dict[str, float] | None = None
    simulation: Annotated[SimulationSummary | None, BeforeValidator(_none_if_no_rig)] = None
    config: dict[str, Any] | None = None
    retest: RetestSummary | None = None  # this test repeats a MARGINAL
    # this MARGINAL was retested: found beside it when a report is drawn, never written (exclude)
    retested_by: RetestedBy | None = Field(None, exclude=True)
    escalation: EscalationSummary | None = None  # the same valve INVALID twice: it may be seized
    part: PartDiagnosis | None = None  # the part at fault (schema 11 on; None in older records: the valve alone)
    files: RecordFiles = RecordFiles()

    model_config = ConfigDict(frozen=True, extra="allow", populate_by_name=True)

    @property
    def problem_flags(self) -> Problem:
        """The recorded problems as values (a name this edc-bench does not know, a newer one's, left out: the
        record's consistency check names it)."""
        known = [name for name in self.problems if name.upper().replace(" ", "_") in Problem.__members__]
        return Problem.from_names(known)

    @property
    def advice(self) -> Advice:
        """What the technician does next (:func:`~edc_bench.records.advice.advice`), from the verdict, the problems
        and the abort's kind as recorded."""
        abort = self.loop.abort
        return advice(self.verdict, self.problem_flags, abort.kind if abort is not None else None, self.part)

    @property
    def part_diagnosis(self) -> PartDiagnosis:
        """Which part is at fault, as recorded; "valve only judged" for a record from before the part diagnosis."""
        return self.part if self.part is not None else VALVE_ONLY

    @property
    def invalid_cause(self) -> Cause:
        """Who this test points at if INVALID (:func:`~edc_bench.records.advice.invalid_cause`), as recorded."""
        abort = self.loop.abort
        return invalid_cause(self.problem_flags, abort.kind if abort is not None else None)

    @property
    def invalid_area(self) -> Area | None:
        """Where this test points the technician if INVALID (:func:`~edc_bench.records.advice.invalid_area`); None
        for any other verdict."""
        if self.verdict != Verdict.INVALID:
            return None
        abort = self.loop.abort
        return invalid_area(self.problem_flags, abort.kind if abort is not None else None)

    @property
    def simulated_rig(self) -> bool:
        """The test ran against the simulated rig (its record holds the simulated valve)."""
        return self.simulation is not None

    @property
    def real_time(self) -> bool:
        """The test ran on the wall clock (a rig on a bus), not in simulated time."""
        return self.clock == ClockKind.REAL_TIME


def undeclared_keys(record: Record) -> list[str]:
    """Every key of ``record`` the schema does not declare, as dotted paths (a test holds the writer to none)."""
    found: list[str] = []

    def walk(value: Any, path: str) -> None:
        if isinstance(value, BaseModel):
            found.extend(f"{path}{key}" for key in (value.model_extra or {})
                         if not (isinstance(value, RecordFiles) and key.endswith("_error")))
            for name in type(value).model_fields:
                walk(getattr(value, name), f"{path}{name}.")
        elif isinstance(value, dict):
            for key, item in value.items():
                if isinstance(item, BaseModel):
                    walk(item, f"{path}{key}.")

    walk(record, "")
    return found
