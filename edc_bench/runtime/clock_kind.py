"""What a clock's time is: simulated (lockstep with an in-process rig) or real (the wall clock). A clock says it
(:attr:`~edc_bench.runtime.clock.Clock.kind`), a wrapper passes its inner clock's on, and the record keeps it as
``clock``: nothing asks which class a clock is (a wrapped simulated clock was once recorded as real time)."""

from __future__ import annotations

import enum


class ClockKind(enum.StrEnum):
    """A clock's kind, as record.json spells it (``clock``)."""

    SIMULATED = "simulated"
    REAL_TIME = "real-time"


__all__ = ["ClockKind"]
