"""A command the tick engine made, as a value: its bytes and what its driver needs to send it and await its reply.

As moteus's ``make_*`` builders return a command that says which reply it expects, :class:`BenchCommand` carries,
beside the ``BENCH_CMD`` payload, its counter (the rig's reply echoes it: the reply it expects), the tick it runs
(None for a SAFE outside the ticks), that tick's deadline, and the last clock time its reply is of use. A driver
sends :attr:`BenchCommand.payload` and waits with :meth:`BenchCommand.is_reply` until
:attr:`BenchCommand.reply_by_s`; it never reads the engine's counter.
"""

from __future__ import annotations

from typing import NamedTuple

from edc_bench.protocol import Mode, RigFeedback


class BenchCommand(NamedTuple):
    """One ``BENCH_CMD`` made by :class:`~edc_bench.engine.tick.TickEngine` (immutable; a tuple, made every tick in
    a fraction of a frozen dataclass's time).

    Attributes
    ----------
    payload : bytes
        The frame's 8 bytes, CRC included, as sent.
    counter : int
        The frame's rolling counter (0-255); the rig's reply carries it back.
    mode : Mode
        SAFE or RUN.
    drive_v : float
        The drive commanded (V; 0 for SAFE).
    reference_mm : float
        The rack position the drive is meant to reach (mm; 0 for SAFE), as the frame carries it (clipped to the
        field's range).
    tick : int or None
        The tick it runs (RUN), None for a SAFE outside the ticks.
    deadline_s : float
        Clock time it is due: its tick's deadline, or when a SAFE was made (NaN where the driver gave none, as
        replay does).
    reply_by_s : float
        The last clock time its reply is of use: for a tick, the deadline of the last tick that may still use the
        sample (``acceptance.max_reply_age_ms``); for a SAFE, what the driver allows it (NaN: not given).
    """

    payload: bytes
    counter: int
    mode: Mode
    drive_v: float
    reference_mm: float
    tick: int | None
    deadline_s: float
    reply_by_s: float

    def is_reply(self, reply: RigFeedback | None) -> bool:
        """True when ``reply`` answers this command (it echoes the counter)."""
        return reply is not None and reply.counter == self.counter


__all__ = ["BenchCommand"]
