"""Whether the rack follows its reference: the loop's check for a stuck rack or sensor.

A rack counts as not following when it stays more than ``acceptance.max_tracking_error_mm`` off its
reference for ``acceptance.tracking_error_ticks`` ticks in a row. The time matters: a sticky valve on
a pump the variant's model fits badly (a faulty valve, its friction not yet learnt, on a solenoid whose
force varies +/-30 % over the swing) sticks for up to 50 ms at a time and then breaks away, which is
stick-slip and not a fault; a jammed rack or a dead sensor stays off for good. The reason says how far
the rack moved while it was off, which tells a stuck rack or sensor (it did not move) from a loop that
cannot hold the rack (it moved, but not with the reference).
"""

from __future__ import annotations

from dataclasses import dataclass, field

from edc_bench.engine.abort_figures import OffReferenceFigures


@dataclass
class OffReferenceRun:
    """The current run of ticks with the rack more than ``max_error_mm`` off its reference.

    Parameters
    ----------
    max_error_mm : float
        How far the rack may stray from its reference, mm.
    ticks_limit : int
        Ticks in a row beyond ``max_error_mm`` that end the test.
    """

    max_error_mm: float
    ticks_limit: int
    ticks: int = 0
    _low_mm: float = field(default=0.0, repr=False)
    _high_mm: float = field(default=0.0, repr=False)

    def update(self, reference_mm: float, position_mm: float) -> bool:
        """Take one tick's reference and measured position; True once the limit is reached."""
        if abs(reference_mm - position_mm) <= self.max_error_mm:
            self.ticks = 0
            return False
        if self.ticks == 0:
            self._low_mm = self._high_mm = position_mm
        else:
            self._low_mm = min(self._low_mm, position_mm)
            self._high_mm = max(self._high_mm, position_mm)
        self.ticks += 1
        return self.ticks >= self.ticks_limit

    @property
    def moved_mm(self) -> float:
        """How far the rack moved (peak to peak) during the current run, mm."""
        return self._high_mm - self._low_mm if self.ticks else 0.0

    def figures(self) -> OffReferenceFigures:
        """The current run as an abort's figures (:attr:`~edc_bench.engine.outcome.AbortKind.OFF_REFERENCE`)."""
        return OffReferenceFigures(max_error_mm=self.max_error_mm, ticks=self.ticks, moved_mm=self.moved_mm)


__all__ = ["OffReferenceRun"]
