"""The figures behind an abort, typed per kind: what :func:`~edc_bench.engine.outcome.describe` says and code reads.

Each :class:`~edc_bench.engine.outcome.AbortKind` has its own frozen class of figures (:data:`FIGURES`), so a
sentence, the PC-stall rule and a test read named attributes, never a mapping's string keys. The record keeps them
as a mapping (:meth:`AbortFigures.as_dict`, ``loop.abort.figures`` in record.json) and reads them back with
:func:`figures_from` (a figure an older record lacks takes its default: NaN, 0, "" or none).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass


@dataclass(frozen=True, kw_only=True)
class AbortFigures:
    """Figures every abort may carry.

    Attributes
    ----------
    adapter_refused : int
        Frames of ours the CAN adapter refused (BEL) during the test (0: none; slcan only).
    """

    adapter_refused: int = 0

    def as_dict(self) -> dict[str, object]:
        """The record's form: each figure by its name (``adapter_refused`` last, and only when there were some)."""
        out: dict[str, object] = {f.name: _plain(getattr(self, f.name)) for f in dataclasses.fields(self)
                                  if f.name != "adapter_refused"}
        if self.adapter_refused:
            out["adapter_refused"] = self.adapter_refused
        return out


def _plain(value: object) -> object:
    return list(value) if isinstance(value, tuple) else value


@dataclass(frozen=True, kw_only=True)
class NoFigures(AbortFigures):
    """An abort that needs no figures (no reply to the first SAFE, another host, interrupted)."""


@dataclass(frozen=True, kw_only=True)
class RigNotReadyFigures(AbortFigures):
    """The rig did not report READY in time."""

    timeout_s: float = math.nan
    state: str = ""  # the rig's last state, or "no heartbeat"


@dataclass(frozen=True, kw_only=True)
class RigFaultFigures(AbortFigures):
    """Fault flags in a reply (:class:`~edc_bench.engine.outcome.RigFaultFlag` values)."""

    flags: tuple[str, ...] = ()


@dataclass(frozen=True, kw_only=True)
class AmplifierOffFigures(AbortFigures):
    """The amplifier went off while running."""

    state: str = ""
    fault_code: str = ""


@dataclass(frozen=True, kw_only=True)
class RigFaultStateFigures(AbortFigures):
    """The rig's heartbeat said FAULT."""

    fault_code: str = ""


@dataclass(frozen=True, kw_only=True)
class SilenceFigures(AbortFigures):
    """Commands in a row with no reply at all."""

    in_row: int = 0
    limit: int = 0
    bad_replies: int = 0  # replies that failed their CRC check in the test
    too_old: int = 0  # replies that came, too old to use


@dataclass(frozen=True, kw_only=True)
class SlowLinkFigures(AbortFigures):
    """Commands in a row without a usable reply, the replies coming too old."""

    in_row: int = 0
    limit: int = 0
    too_old: int = 0
    limit_from_watchdog: bool = False  # the limit is the rig's watchdog time, not max_missed_replies_in_row
    max_reply_age_ms: float = math.nan


@dataclass(frozen=True, kw_only=True)
class RepliesMissingFigures(AbortFigures):
    """More replies missing than the test may lose in all."""

    missed: int = 0
    ticks: int = 0  # run when it ended
    limit_fraction: float = math.nan
    planned: int = 0  # the test's length in ticks, that the limit is a fraction of (0: a record before 2026-11-28)


@dataclass(frozen=True, kw_only=True)
class HeartbeatLostFigures(AbortFigures):
    """No heartbeat for longer than the timeout."""

    silent_ms: float = math.nan
    limit_ms: float = math.nan


@dataclass(frozen=True, kw_only=True)
class SampleOutOfRangeFigures(AbortFigures):
    """A sample no rig can give."""

    position_mm: float = math.nan
    current_a: float = math.nan
    position_min_mm: float = math.nan
    position_max_mm: float = math.nan
    current_max_a: float = math.nan


@dataclass(frozen=True, kw_only=True)
class OffReferenceFigures(AbortFigures):
    """The rack off its reference for too long (:class:`~edc_bench.engine.tracking.OffReferenceRun`)."""

    max_error_mm: float = math.nan
    ticks: int = 0
    moved_mm: float = math.nan


@dataclass(frozen=True, kw_only=True)
class BusFloodedFigures(AbortFigures):
    """More frames in one tick than the budget."""

    limit: int = 0


@dataclass(frozen=True, kw_only=True)
class ErrorFigures(AbortFigures):
    """A bus error or an internal error: the exception, as ``Type: message``."""

    error: str = ""


@dataclass(frozen=True, kw_only=True)
class LogEndsFigures(AbortFigures):
    """A raw CAN log that ends before the test could (replay)."""

    ticks: int = 0
    planned: int = 0


@dataclass(frozen=True, kw_only=True)
class RecordedFigures(AbortFigures):
    """An abort read from a record written before aborts had kinds: its sentence only."""

    sentence: str = ""


def figures_from(cls: type[AbortFigures], data: Mapping[str, object] | None) -> AbortFigures:
    """The figures of class ``cls`` a record's mapping holds: keys it does not know are left out; a figure it
    lacks, or holds as something its type cannot be made from (a hand-edited record), takes its default."""
    data = data if isinstance(data, Mapping) else {}
    values = {}
    for f in dataclasses.fields(cls):
        if f.name in data:
            value = _as(type(f.default), data[f.name])  # every figure has a default, of the figure's type
            if value is not None:
                values[f.name] = value
    return cls(**values)  # type: ignore[arg-type]


def _as(kind: type, value: object) -> object:
    """``value`` as a figure of type ``kind`` (float, int, bool, str or a tuple of str), or None if it cannot be."""
    try:
        if kind is float:
            return float(value)  # type: ignore[arg-type]
        if kind is bool:
            return value if isinstance(value, bool) else None
        if kind is int:
            return int(value) if not isinstance(value, float) or value.is_integer() else None  # type: ignore[arg-type]
        if kind is str:
            return value if isinstance(value, str) else None
        if kind is tuple:
            return tuple(str(v) for v in value) if isinstance(value, (list, tuple)) else None
    except (TypeError, ValueError, OverflowError):  # OverflowError: an integer too large for a float
        return None
    return None


__all__ = ["AbortFigures", "AmplifierOffFigures", "BusFloodedFigures", "ErrorFigures", "HeartbeatLostFigures",
           "LogEndsFigures", "NoFigures", "OffReferenceFigures", "RecordedFigures", "RepliesMissingFigures",
           "RigFaultFigures", "RigFaultStateFigures", "RigNotReadyFigures", "SampleOutOfRangeFigures",
           "SilenceFigures", "SlowLinkFigures", "figures_from"]
