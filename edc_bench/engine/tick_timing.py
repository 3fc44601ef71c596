"""How a run kept its tick deadlines, as one value: what the verdict's trust rule counts and the record keeps."""

from __future__ import annotations

import math

from typing import Annotated, Any

from pydantic import BaseModel, BeforeValidator, ConfigDict


def _zero_if_none(value: Any) -> Any:
    return 0 if value is None else value


# A count or a time that a damaged or hand-edited record holds as null reads as none counted (as the record's
# readers took it when timing was a plain mapping), not as a record refused.
CountOrZero = Annotated[int, BeforeValidator(_zero_if_none)]
SecondsOrZero = Annotated[float, BeforeValidator(_zero_if_none)]


class TickTiming(BaseModel):
    """How the loop kept its tick deadlines: the record's ``timing`` section, read and written as this model.

    Attributes
    ----------
    ticks : int
        Ticks that ran (a tick lost to a host stall did not).
    lateness_p50_us, lateness_p99_us, lateness_p999_us, lateness_max_us : float or None
        Percentiles of how late the ticks that ran started (NaN, None in a record: no tick ran).
    ticks_late : int
        Ticks that started more than a period late.
    missed_replies : int
        Ticks whose reply did not come in time.
    cpu_steal_s : float
        CPU time the hypervisor took from this machine during the test.
    first_tick_unix_s : float or None
        When the first tick ran, wall-clock time.
    scheduling : str or None
        The loop thread's scheduling (real-time runs only).
    stop_check_max_us : float or None
        The early stop's longest call (tests with an early stop only).
    rig_on_this_pc : bool or None
        The rig is a process on this PC (the simulated rig process, or one served on a loopback socket or a
        pseudo-terminal): replies it stopped sending are the PC's doing, never a cable's. None: a rig on a bus, or
        not known (older records).
    """

    model_config = ConfigDict(frozen=True, extra="allow")  # a newer edc-bench's figures kept, not refused

    ticks: CountOrZero = 0
    lateness_p50_us: float | None = None
    lateness_p99_us: float | None = None
    lateness_p999_us: float | None = None
    lateness_max_us: float | None = None
    ticks_late: CountOrZero = 0
    missed_replies: CountOrZero = 0
    cpu_steal_s: SecondsOrZero = 0.0
    first_tick_unix_s: float | None = None
    scheduling: str | None = None
    stop_check_max_us: float | None = None
    rig_on_this_pc: bool | None = None

    @property
    def lateness_us(self) -> tuple[float, float, float] | None:
        """p50, p99 and max lateness (us); None if a figure is missing or not a number (no tick ran)."""
        figures = (self.lateness_p50_us, self.lateness_p99_us, self.lateness_max_us)
        if any(value is None or math.isnan(value) for value in figures):
            return None
        return figures  # type: ignore[return-value]
