"""Plain log lines for a test when the output is not a terminal (CI, pipes, log files)."""

from __future__ import annotations

from typing import IO, Any

from edc_bench.ui.snapshot import Snapshot


class PlainLog:
    """A :class:`~edc_bench.runtime.loop.LoopObserver` writing a line per phase and one every 5 s of test.

    Parameters
    ----------
    stream : file
        Where the lines go (stderr, so stdout stays the result).
    every_s : float
        Test seconds between progress lines.
    """

    def __init__(self, stream: IO[str], every_s: float = 5.0) -> None:
        self.stream = stream
        self.every_s = every_s
        self.snapshot = Snapshot()
        self._next_s = 0.0

    def _write(self, line: str) -> None:
        try:
            self.stream.write(line + "\n")
            self.stream.flush()
        except (OSError, ValueError):  # the reader went away: the test goes on, its record is what counts
            pass

    def phase(self, name: str) -> None:
        """Log the phase."""
        self.snapshot.enter(name)
        self._write(f"[{self.snapshot.t_s:5.1f} s] phase: {name}")

    def tick(self, k: int, loop: Any) -> None:
        """Log progress every ``every_s`` seconds of test."""
        s = self.snapshot
        s.update(k, loop)
        if s.t_s + 1e-9 < self._next_s:
            return
        self._next_s += self.every_s
        # the live panel's words: "10.0 s left" alone, after "at most 30 s", read as a contradiction
        self._write(f"[{s.t_s:5.1f} s] {s.time_left_words} | rack {s.position_mm:6.2f} mm, reference "
                    f"{s.reference_mm:6.2f} mm | af {s.af:8.5f} V | a1 {s.a1:9.6f} V s/mm | ticks late or lost {s.ticks_late_or_lost}, "
                    f"missed replies {s.missed_replies}")
