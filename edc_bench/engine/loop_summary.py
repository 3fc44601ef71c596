"""The loop's part of a test's record: what happened in the loop (:class:`~edc_bench.engine.outcome.LoopOutcome`)
as the model record.json's ``loop`` section is written from and read back as.

Its ``abort`` is the engine's own :class:`~edc_bench.engine.outcome.Abort` (kind, the kind's typed figures, when),
written as :meth:`~edc_bench.engine.outcome.Abort.as_dict` and read back by
:meth:`~edc_bench.engine.outcome.Abort.from_dict`: the abort has one shape from the tick that decided it to the
record and back. The stop rule's decision is the record's own ``stop`` section
(:class:`~edc_bench.records.schema.StopSummary`); an older record's copy of it under ``loop`` is kept as an
unknown key.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from typing import Annotated, Any

from pydantic import Field, PlainSerializer, PlainValidator

from edc_bench.engine.outcome import Abort, LoopOutcome
from edc_bench.section import Section


def _abort_of(value: Any) -> Abort:
    """The abort a record's ``loop.abort`` holds; a value that is none is refused with what is wrong (a
    ValueError, which pydantic reports with the field)."""
    if isinstance(value, Abort):
        return value
    if not isinstance(value, Mapping):
        raise ValueError("an abort is a mapping with its 'kind', 'figures' and 'time_s'")
    if "kind" not in value:
        raise ValueError("an abort names its 'kind'")
    figures = value.get("figures")
    if figures is not None and not isinstance(figures, Mapping):
        raise ValueError("an abort's 'figures' are a mapping of each figure by its name")
    return Abort.from_dict({**value, "time_s": _seconds_or_none(value.get("time_s"))})  # a kind no name: ValueError


def _seconds_or_none(time_s: Any) -> float | None:
    """An abort's time as a float (None: before the ticks began); anything else refused."""
    if time_s is None:
        return None
    try:
        if isinstance(time_s, bool) or not isinstance(time_s, (int, float)) or not math.isfinite(float(time_s)):
            raise ValueError
        return float(time_s)
    except (ValueError, OverflowError):
        raise ValueError("an abort's 'time_s' is a number of seconds or null") from None


#: The engine's abort as a record's field: validated from its record form, written as it.
RecordedAbort = Annotated[Abort, PlainValidator(_abort_of), PlainSerializer(lambda abort: abort.as_dict())]


class LoopSummary(Section):
    """What happened in the loop: ticks, replies, the bus, the abort (:class:`~edc_bench.engine.outcome.LoopOutcome`).

    Built once from the outcome (:meth:`of`); read back from a record as the same model. A figure an older record
    lacks takes its default (``ticks_planned``, ``safe_confirmed``, ``clock_origin_unix_s``: None, not known).
    """

    ticks_planned: int | None = None
    ticks_run: int = 0
    missed_replies: int = 0
    max_missed_in_row: int = 0
    max_unanswered_in_row: int = 0
    bad_replies: int = 0
    rig_state_at_start: str | None = None
    fw_version: str | None = None
    safe_confirmed: bool | None = None
    heartbeats: int = 0
    cpu_steal_s: float = 0.0
    ticks_start_s: float = 0.0
    first_tick_unix_s: float | None = None
    clock_origin_unix_s: float | None = None
    replies_too_old: int = 0
    gaps: int = 0
    ticks_lost: int = 0
    ticks_late: int = 0
    reply_age_ticks: dict[int, int] = Field(default_factory=dict)  # reply age in ticks -> replies
    other_frames: int = 0
    bus_bad_lines: int = 0
    bus_bad_line_samples: list[str] = Field(default_factory=list)
    bus_device_errors: int = 0
    frames_dropped: int = 0
    events: list[str] = Field(default_factory=list)
    stop_check_max_s: float = 0.0
    abort: RecordedAbort | None = None
    abort_reason: str | None = None  # the abort's sentence, for a person reading record.json
    abort_time_s: float | None = None

    @classmethod
    def of(cls, outcome: LoopOutcome) -> LoopSummary:
        """The summary of ``outcome``: each of its figures under its own name (one this model does not declare kept
        as an extra, which the writer's test of undeclared keys names), the abort's sentence beside it. The stop
        rule's decision is the record's own ``stop`` section."""
        figures = {f.name: getattr(outcome, f.name) for f in dataclasses.fields(outcome) if f.name != "stop"}
        return cls(**figures, abort_reason=outcome.abort_reason, abort_time_s=outcome.abort_time_s)


__all__ = ["LoopSummary", "RecordedAbort"]
