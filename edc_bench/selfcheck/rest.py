"""The rig at rest: the LVDT's zero and the current sensor's zero, read with the amplifier off.

With no drive the rack sits on its mechanical stop (the return spring's
preload holds it there) and no current flows in the coil. What the rig then
reports is its sensors' zero: a rack position that is not the registered
one means the LVDT's zero has moved (a knock on its mounting, a loose
core), a current that is not the registered one means the current sensor's
zero has moved. The bench sends SAFE commands at its loop rate, which keep
the amplifier off, and reads every reply's samples.

The ICD's frame carries no negative rack position: a reading below 0 mm
arrives as 0. The zero is therefore the median of the readings, which holds
while fewer than half of them are at the floor; when more are, the LVDT
reads 0 mm or less at rest and :attr:`RestReading.lvdt_at_floor` says so.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from edc_bench.canlib import can
from edc_bench.config.models import Variant
from edc_bench.errors import RigError
from edc_bench.protocol import Icd, Mode, RigState, default_icd
from edc_bench.rigcheck.session import RigSession
from edc_bench.runtime.clock import Clock

#: SAFE commands whose samples make the reading (0.5 s at 1 kHz).
REST_SAMPLES = 500


@dataclass(frozen=True)
class RestReading:
    """The rig's sensors with the rack at rest and no drive.

    Attributes
    ----------
    lvdt_zero_mm : float
        Median rack position read (mm).
    current_zero_a : float
        Mean coil current read (A).
    lvdt_sd_mm, current_sd_a : float
        Standard deviation of the readings (the sensors' noise).
    samples : int
        Replies the figures come from.
    lvdt_at_floor : bool
        More than half the position readings were 0.000 mm, the least the frame carries: the LVDT reads 0 mm or
        less, and ``lvdt_zero_mm`` is an upper bound.
    """

    lvdt_zero_mm: float
    current_zero_a: float
    lvdt_sd_mm: float
    current_sd_a: float
    samples: int
    lvdt_at_floor: bool


def rest_reading(positions_mm: np.ndarray, currents_a: np.ndarray) -> RestReading:
    """The rest figures of the samples read (pure).

    Parameters
    ----------
    positions_mm, currents_a : numpy.ndarray
        Rack position and coil current of each reply.

    Returns
    -------
    RestReading
    """
    x = np.asarray(positions_mm, dtype=float)
    i = np.asarray(currents_a, dtype=float)
    return RestReading(lvdt_zero_mm=float(np.median(x)), current_zero_a=float(np.mean(i)),
                       lvdt_sd_mm=float(np.std(x)), current_sd_a=float(np.std(i)), samples=len(x),
                       lvdt_at_floor=bool(np.mean(x <= 0.0) > 0.5))


def measure_rest(bus: can.BusABC, clock: Clock, variant: Variant, icd: Icd | None = None,
                 samples: int = REST_SAMPLES) -> RestReading:
    """Read the rig's sensors at rest: wait for READY, then SAFE commands at the loop rate, one sample each.

    Parameters
    ----------
    bus : can.BusABC
        The bench's end of the bus.
    clock : Clock
        Real time on a rig; the simulated clock stepping an in-process rig in simulated time.
    variant : Variant
        The loop period and how long to wait for READY (``acceptance.ready_timeout_s``).
    icd : Icd, optional
        The compiled ICD (the packaged one).
    samples : int, optional
        Replies to read (:data:`REST_SAMPLES`).

    Returns
    -------
    RestReading

    Raises
    ------
    RigError
        The rig did not report READY in time, answered too few commands, or flagged a fault at rest.
    """
    session = RigSession(bus, clock, icd or default_icd())
    period = variant.controller.period_s
    limit = variant.acceptance.ready_timeout_s
    rearmed = False
    while True:
        session.wait(0.01)
        beats = [beat for _, beat in session.heartbeats(0.0) if beat is not None]
        state = beats[-1].state if beats else None
        if state is RigState.READY:
            break
        if state in (RigState.FAULT, RigState.RUNNING) and not rearmed:
            session.command(Mode.SAFE)  # re-arm, as a test does
            rearmed = True
        if session.now_s() >= limit:
            raise RigError(f"the rig did not report READY within {limit:g} s (last state: "
                           f"{state.name if state is not None else 'no heartbeat'}): check its power and the bus")
    start = session.now_s()
    for _ in range(samples):
        session.command(Mode.SAFE)
        session.wait(period)
    session.wait(0.01)  # the last replies on their way
    replies = [reply for _, reply in session.feedback(start) if reply is not None]
    if len(replies) < 0.9 * samples:
        raise RigError(f"the rig answered {len(replies)} of {samples} SAFE commands at rest: check the bus "
                       "('edc-bench rig-check')")
    faults = [reply for reply in replies if reply.any_fault]
    if faults:
        raise RigError("the rig flagged a fault at rest (" + ", ".join(
            name for name in ("watchdog_tripped", "over_current", "lvdt_fault", "travel_limit")
            if getattr(faults[0], name)) + "): clear it, check the LVDT and the coil's wiring, then run again")
    return rest_reading(np.array([r.position_mm for r in replies]), np.array([r.current_a for r in replies]))
