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

    def update(self, reference_mm: float, position_mm: float) -> str | None:
        """Take one tick's reference and measured position; return the abort reason once the limit is reached."""
        if abs(reference_mm - position_mm) <= self.max_error_mm:
            self.ticks = 0
            return None
        if self.ticks == 0:
            self._low_mm = self._high_mm = position_mm
        else:
            self._low_mm = min(self._low_mm, position_mm)
            self._high_mm = max(self._high_mm, position_mm)
        self.ticks += 1
        if self.ticks < self.ticks_limit:
            return None
        return self.reason()

    @property
    def moved_mm(self) -> float:
        """How far the rack moved (peak to peak) during the current run, mm."""
        return self._high_mm - self._low_mm if self.ticks else 0.0

    def reason(self) -> str:
        """The abort reason for the current run."""
        moved_mm = self.moved_mm
        if moved_mm < 0.5 * self.max_error_mm:
            why = "stuck rack or sensor"
        else:
            why = ("it moves, but the loop cannot hold it: the variant's gains or model do not fit this pump, "
                   "or the drive's polarity is reversed")
        return (f"rack does not follow its reference: more than {self.max_error_mm:g} mm off for {self.ticks} "
                f"ticks, moving {moved_mm:.2f} mm meanwhile ({why})")


__all__ = ["OffReferenceRun"]
