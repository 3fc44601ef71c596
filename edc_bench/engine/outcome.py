"""How a test ended, as values: what code branches on, and the one place their sentences are made.

An abort is an :class:`Abort`: a :class:`AbortKind` and the figures behind
it. Code decides by the kind (whether SAFE may be sent, the exit code,
what the technician is told to check); people read :func:`describe`, the
only place an abort becomes a sentence. A test that ended early on its
own terms (the verdict was certain, the model does not fit) carries a
:class:`StopReason`; records keep both the kind and the sentence.

Hierarchy::

    LoopOutcome          what the loop (or replay) saw, beyond the trace
    ├── abort: Abort     why the test was cut short, if it was
    │   └── kind: AbortKind
    └── stop: StopDecision  the stop rule's decision (reason: StopReason), if it ended the test early
"""

from __future__ import annotations

import dataclasses
import enum
from dataclasses import dataclass, field
from typing import Any

from edc_bench.engine.abort_figures import (
    AbortFigures,
    AmplifierOffFigures,
    BusFloodedFigures,
    ErrorFigures,
    HeartbeatLostFigures,
    LogEndsFigures,
    NoFigures,
    OffReferenceFigures,
    RecordedFigures,
    RepliesMissingFigures,
    RigFaultFigures,
    RigFaultStateFigures,
    RigNotReadyFigures,
    SampleOutOfRangeFigures,
    SilenceFigures,
    SlowLinkFigures,
    figures_from,
)
from edc_bench.section import FeaturePair


class RigFaultFlag(enum.StrEnum):
    """A fault bit of the rig's feedback, as a rig-fault abort's ``flags`` name it (the values are what record.json
    stores and people read)."""

    WATCHDOG_TRIPPED = "watchdog tripped"
    OVER_CURRENT = "over-current"
    LVDT_FAULT = "LVDT fault"
    TRAVEL_LIMIT = "travel limit"


class AbortKind(enum.StrEnum):
    """Why a test was cut short. The values are what record.json stores (``loop.abort.kind``)."""

    RIG_NOT_READY = "rig not ready"
    NO_SYNC_REPLY = "no reply to the first SAFE"
    RIG_FAULT = "rig fault flags"
    AMPLIFIER_OFF = "amplifier off"
    RIG_FAULT_STATE = "rig in FAULT"
    SILENCE = "rig silent"
    SLOW_LINK = "slow link"
    REPLIES_MISSING = "replies missing"
    HEARTBEAT_LOST = "heartbeat lost"
    SAMPLE_OUT_OF_RANGE = "sample out of range"
    OFF_REFERENCE = "rack off its reference"
    BUS_FLOODED = "bus flooded"
    FOREIGN_COMMAND = "another host commands the rig"
    BUS_ERROR = "bus error"
    INTERRUPTED = "interrupted"
    INTERNAL_ERROR = "internal error"
    #: a raw CAN log that ends before the test could (replay)
    LOG_ENDS = "log ends"
    #: an abort read from a record written before aborts had kinds: known only by its sentence
    RECORDED = "recorded"


#: Each kind's figures (:mod:`edc_bench.engine.abort_figures`).
FIGURES: dict[AbortKind, type[AbortFigures]] = {
    AbortKind.RIG_NOT_READY: RigNotReadyFigures,
    AbortKind.NO_SYNC_REPLY: NoFigures,
    AbortKind.RIG_FAULT: RigFaultFigures,
    AbortKind.AMPLIFIER_OFF: AmplifierOffFigures,
    AbortKind.RIG_FAULT_STATE: RigFaultStateFigures,
    AbortKind.SILENCE: SilenceFigures,
    AbortKind.SLOW_LINK: SlowLinkFigures,
    AbortKind.REPLIES_MISSING: RepliesMissingFigures,
    AbortKind.HEARTBEAT_LOST: HeartbeatLostFigures,
    AbortKind.SAMPLE_OUT_OF_RANGE: SampleOutOfRangeFigures,
    AbortKind.OFF_REFERENCE: OffReferenceFigures,
    AbortKind.BUS_FLOODED: BusFloodedFigures,
    AbortKind.FOREIGN_COMMAND: NoFigures,
    AbortKind.BUS_ERROR: ErrorFigures,
    AbortKind.INTERRUPTED: NoFigures,
    AbortKind.INTERNAL_ERROR: ErrorFigures,
    AbortKind.LOG_ENDS: LogEndsFigures,
    AbortKind.RECORDED: RecordedFigures,
}


class StopReason(enum.StrEnum):
    """Why a test ended where it did. The values are what record.json stores (``stop.reason``)."""

    VERDICT_CERTAIN = "verdict certain"
    MODEL_DOES_NOT_FIT = "model does not fit"
    FULL_LENGTH = "full length"
    ABORTED = "aborted"


@dataclass(frozen=True)
class PeriodDecision:
    """The stop rule's last period-end decision, for the live view: what the verdict will rest on
    (the live panel's process unpickles it: declared here, in a module that process imports already).

    Attributes
    ----------
    periods : int
        Whole excitation periods the fit took.
    af_rel, a1_rel : float
        af and a1 over the new-valve baseline, at the interval's centre.
    af_half_width_rel, a1_half_width_rel : float
        The half widths of their interval, relative to the baseline.
    verdict : str
        The verdict at the centre; "" while the fit is not trusted.
    """

    periods: int
    af_rel: float
    a1_rel: float
    af_half_width_rel: float
    a1_half_width_rel: float
    verdict: str


@dataclass(frozen=True)
class StopDecision:
    """The stop rule's decision to end a test at a period's end, with the figures it rests on (the record's ``stop``
    section holds them, :class:`~edc_bench.records.schema.StopSummary`, under the same names).

    Attributes
    ----------
    reason : StopReason
        :attr:`StopReason.VERDICT_CERTAIN` or :attr:`StopReason.MODEL_DOES_NOT_FIT`.
    time_s : float
        The trace time of the period's end it was decided at.
    periods : int
        The whole excitation periods it rests on.
    verdict : str or None
        The verdict it is certain of (a certain verdict only).
    confidence : float or None
        The variant's verdict confidence the interval was drawn at (a certain verdict only).
    features_rel, half_width_rel, misfit_half_width_rel, baseline_half_width_rel, residual_half_width_rel : FeaturePair
        af's and a1's ratio to the baseline, the interval's half width and its parts (a certain verdict only).
    problems : tuple of str
        Why the model does not fit (that reason only).
    decided_s : float or None
        When the loop took the decision (after ``time_s`` in real time: the rule's work spreads over ticks); set
        by :meth:`with_decided`.
    """

    reason: StopReason
    time_s: float
    periods: int
    verdict: str | None = None
    confidence: float | None = None
    features_rel: FeaturePair | None = None
    half_width_rel: FeaturePair | None = None
    misfit_half_width_rel: FeaturePair | None = None
    baseline_half_width_rel: FeaturePair | None = None
    residual_half_width_rel: FeaturePair | None = None
    problems: tuple[str, ...] = ()
    decided_s: float | None = None

    def with_decided(self, decided_s: float) -> StopDecision:
        """The same decision, taken by the loop at trace time ``decided_s``."""
        return dataclasses.replace(self, decided_s=decided_s)


#: What a technician checks, by the kind of abort: the rig and its link, the PC, or the pump on it.
CHECK_RIG = "check the rig: powered, its amplifier and sensors, the CAN cable and termination"
CHECK_PC = "check the PC: close other programs, or run check-station"
CHECK_PUMP = "check the mounting: the valve seated, the rack free to move, the coil's connector"
CHECK_BUS = "check the bus: only this bench on it, the adapter and its cable"


@dataclass(frozen=True)
class Abort:
    """Why a test was cut short, with the figures behind it.

    Parameters
    ----------
    kind : AbortKind
        What happened; code branches on this.
    figures : AbortFigures
        The numbers and names behind it (limits, counts, flags): the kind's own class (:data:`FIGURES`);
        :class:`~edc_bench.engine.abort_figures.NoFigures` for a kind that has none.
    time_s : float or None
        Trace time at which the abort was decided (None before the ticks began).

    Raises
    ------
    TypeError
        If ``figures`` is not the kind's class (a bug in the code that made the abort).
    """

    kind: AbortKind
    figures: AbortFigures = field(default_factory=NoFigures)
    time_s: float | None = None

    def __post_init__(self) -> None:
        expected = FIGURES[self.kind]
        if type(self.figures) is not expected:
            raise TypeError(f"an abort of kind {self.kind.name} carries {expected.__name__}, "
                            f"not {type(self.figures).__name__}")

    @property
    def sentence(self) -> str:
        """What a person reads (:func:`describe`)."""
        return describe(self)

    @property
    def check(self) -> str:
        """What to check before testing again (:func:`what_to_check`)."""
        return what_to_check(self.kind)

    def as_dict(self) -> dict[str, Any]:
        """The record's form: ``{"kind", "figures", "time_s"}``."""
        return {"kind": str(self.kind), "figures": self.figures.as_dict(), "time_s": self.time_s}

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> Abort:
        """The abort a record holds (:meth:`as_dict`)."""
        kind = AbortKind(data["kind"])
        return cls(kind, figures_from(FIGURES[kind], data.get("figures")), data.get("time_s"))

    def at(self, time_s: float | None) -> Abort:
        """The same abort, decided at trace time ``time_s``."""
        return Abort(self.kind, self.figures, time_s)

    def with_adapter_refused(self, frames: int) -> Abort:
        """The same abort, the CAN adapter having refused ``frames`` of ours."""
        return Abort(self.kind, dataclasses.replace(self.figures, adapter_refused=frames), self.time_s)


def _silence(f: SilenceFigures) -> str:
    why = (f"no valid reply ({f.bad_replies} failed their CRC check in this test)" if f.bad_replies
           else "the rig stopped answering")
    text = f"{f.in_row} replies missing in a row (limit {f.limit}): {why}"
    if f.too_old:
        text += f" ({f.too_old} replies came earlier, too old to use)"
    return text


def _slow_link(f: SlowLinkFigures) -> str:
    source = "the rig's watchdog time" if f.limit_from_watchdog else "acceptance.max_missed_replies_in_row"
    return (f"no usable reply for {f.in_row} ticks in a row (limit {f.limit}, {source}); {f.too_old} "
            f"replies came, but older than acceptance.max_reply_age_ms ({f.max_reply_age_ms:g} ms): the link is "
            "slower than the variant's gains are checked for (raise max_reply_age_ms and retune the gains for that "
            "delay)")


def _off_reference(f: OffReferenceFigures) -> str:
    if f.moved_mm < 0.5 * f.max_error_mm:
        why = "stuck rack or sensor"
    else:
        why = ("it moves, but the loop cannot hold it: the variant's gains or model do not fit this pump, "
               "or the drive's polarity is reversed")
    return (f"rack does not follow its reference: more than {f.max_error_mm:g} mm off for {f.ticks} "
            f"ticks, moving {f.moved_mm:.2f} mm meanwhile ({why})")


_SENTENCES: dict[AbortKind, Any] = {  # each kind's sentence from its own figures (FIGURES)
    AbortKind.RIG_NOT_READY: lambda f: f"rig not READY within {f.timeout_s:g} s ({f.state})",
    AbortKind.NO_SYNC_REPLY: lambda f: "no reply to the first SAFE command",
    AbortKind.RIG_FAULT: lambda f: "rig fault: " + ", ".join(f.flags),
    AbortKind.AMPLIFIER_OFF: lambda f: (f"rig amplifier off while running (rig state {f.state}, "
                                        f"fault code {f.fault_code})"),
    AbortKind.RIG_FAULT_STATE: lambda f: f"rig reported FAULT (fault code {f.fault_code})",
    AbortKind.SILENCE: _silence,
    AbortKind.SLOW_LINK: _slow_link,
    AbortKind.REPLIES_MISSING: lambda f: (
        f"{f.missed} replies missing in {f.ticks} ticks: more than {f.limit_fraction:.1%} of the test's {f.planned} ticks"
        if f.planned else f"{f.missed} of {f.ticks} replies missing (limit {f.limit_fraction:.1%})"),
    AbortKind.HEARTBEAT_LOST: lambda f: (f"rig heartbeat lost: none for {f.silent_ms:.0f} ms "
                                         f"(limit {f.limit_ms:.0f} ms)"),
    AbortKind.SAMPLE_OUT_OF_RANGE: lambda f: (
        f"sample out of range: rack {f.position_mm:.3f} mm, coil {f.current_a:.3f} A "
        f"(plausible {f.position_min_mm:g}..{f.position_max_mm:g} mm, |i| <= {f.current_max_a:g} A)"),
    AbortKind.OFF_REFERENCE: _off_reference,
    AbortKind.BUS_FLOODED: lambda f: (f"bus flooded: more than {f.limit} frames within one tick "
                                      "(acceptance.max_frames_per_tick)"),
    AbortKind.FOREIGN_COMMAND: lambda f: ("another host is sending BENCH_CMD on the bus: a second bench or tool is "
                                          "driving the rig; stop it, then test again"),
    AbortKind.BUS_ERROR: lambda f: f"bus error: {f.error}",
    AbortKind.INTERRUPTED: lambda f: "interrupted by the operator",
    AbortKind.INTERNAL_ERROR: lambda f: f"internal error: {f.error}",
    AbortKind.LOG_ENDS: lambda f: f"the log ends after {f.ticks} of {f.planned} ticks",
    AbortKind.RECORDED: lambda f: f.sentence,
}


def describe(abort: Abort) -> str:
    """The sentence a person reads for ``abort``: the one place an abort becomes words."""
    text: str = _SENTENCES[abort.kind](abort.figures)
    refused = abort.figures.adapter_refused
    if refused:
        text += (f"; the CAN adapter refused {refused} of our frames (BEL): with edc-bench rig, another host may "
                 "own the rig")
    return text


_CHECKS = {
    AbortKind.RIG_NOT_READY: CHECK_RIG,
    AbortKind.NO_SYNC_REPLY: CHECK_RIG,
    AbortKind.RIG_FAULT: CHECK_PUMP + "; " + CHECK_RIG,
    AbortKind.AMPLIFIER_OFF: CHECK_RIG,
    AbortKind.RIG_FAULT_STATE: CHECK_RIG,
    AbortKind.SILENCE: CHECK_RIG,
    AbortKind.SLOW_LINK: CHECK_BUS,
    AbortKind.REPLIES_MISSING: CHECK_BUS,
    AbortKind.HEARTBEAT_LOST: CHECK_RIG,
    AbortKind.SAMPLE_OUT_OF_RANGE: CHECK_PUMP + "; " + CHECK_RIG,
    AbortKind.OFF_REFERENCE: CHECK_PUMP,
    AbortKind.BUS_FLOODED: CHECK_BUS,
    AbortKind.FOREIGN_COMMAND: CHECK_BUS,
    AbortKind.BUS_ERROR: CHECK_BUS,
    AbortKind.INTERRUPTED: "test again when ready",
    AbortKind.INTERNAL_ERROR: "report the bug with the record folder; the rig was sent SAFE",
    AbortKind.LOG_ENDS: "replay the whole log",
    AbortKind.RECORDED: "see the reason",
}


def what_to_check(kind: AbortKind) -> str:
    """What a technician checks before testing again, for an abort of ``kind``."""
    return _CHECKS[kind]


@dataclass
class LoopOutcome:
    """What happened in the loop (or was found again by replay), beyond the trace.

    ``gaps`` counts host stalls that cost whole periods (each skipped, never sent late), ``ticks_lost`` the
    ticks skipped in them; ``ticks_late`` the ticks that ran but started more than a period late.
    """

    ticks_planned: int
    ticks_run: int = 0
    missed_replies: int = 0
    max_missed_in_row: int = 0  # commands in a row without a usable reply (the PID held meanwhile)
    max_unanswered_in_row: int = 0  # commands in a row with no reply at all
    bad_replies: int = 0
    abort: Abort | None = None
    rig_state_at_start: str | None = None
    fw_version: str | None = None
    safe_confirmed: bool = False
    heartbeats: int = 0
    cpu_steal_s: float = 0.0
    ticks_start_s: float = 0.0  # clock time of trace time 0 (the frame log's time base)
    first_tick_unix_s: float | None = None  # wall-clock time the first tick began (start-up measurements)
    replies_too_old: int = 0  # replies that came after max_reply_age_ms: never used
    gaps: int = 0  # host stalls that cost whole periods
    ticks_lost: int = 0  # ticks skipped in those gaps
    ticks_late: int = 0  # ticks that ran, but started more than a period late (the timing summary's figure)
    reply_age_ticks: dict[int, int] = field(default_factory=dict)  # age at arrival (ticks) -> replies
    clock_origin_unix_s: float = 0.0  # Unix time of clock time 0 (the CAN log's timestamps are absolute)
    other_frames: int = 0  # frames of no ICD message: other nodes' traffic, extended, remote or error frames
    bus_bad_lines: int = 0  # lines the bus driver could not read as frames (slcan), skipped
    bus_bad_line_samples: list[str] = field(default_factory=list)
    bus_device_errors: int = 0  # the adapter answered BEL: it refused a command of ours (slcan)
    frames_dropped: int = 0  # frames beyond the CAN log's maximum, counted but not stored
    events: list[str] = field(default_factory=list)
    stop: StopDecision | None = None  # the stop rule's decision, when it ended the test early
    stop_check_max_s: float = 0.0  # the stop rule's longest call (wall time, perf_counter)

    @property
    def aborted(self) -> bool:
        """True if the test was cut short."""
        return self.abort is not None

    @property
    def abort_reason(self) -> str | None:
        """The abort's sentence, for people (None if the test was not aborted)."""
        return None if self.abort is None else self.abort.sentence

    @property
    def abort_time_s(self) -> float | None:
        """Trace time at which the abort was decided."""
        return None if self.abort is None else self.abort.time_s


def abort_from_record(loop: dict[str, Any]) -> Abort | None:
    """The abort a record's ``loop`` entry holds; an older record's (its sentence only) as :attr:`AbortKind.RECORDED`."""
    if loop.get("abort"):
        return Abort.from_dict(loop["abort"])
    if loop.get("abort_reason"):
        return Abort(AbortKind.RECORDED, RecordedFigures(sentence=str(loop["abort_reason"])), loop.get("abort_time_s"))
    return None


__all__ = ["FIGURES", "Abort", "AbortKind", "LoopOutcome", "StopDecision", "StopReason", "abort_from_record",
           "describe", "what_to_check"]
