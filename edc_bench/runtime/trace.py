"""Per-tick trace and raw CAN frames, in preallocated arrays.

The tick writes into arrays sized before the test, so recording allocates
nothing per tick; what was measured up to an abort is all there.
"""

from __future__ import annotations

import numpy as np

PARAMETER_NAMES = ("a3", "a2", "a1", "a0", "b", "af")

# column name -> dtype; units in the names
TRACE_COLUMNS: dict[str, str] = {
    "t_s": "f8",
    "lateness_s": "f8",
    "reply_latency_s": "f8",
    "reference_mm": "f8",
    "reference_velocity_mm_s": "f8",
    "position_mm": "f8",
    "current_a": "f8",
    "drive_v": "f8",
    "feedforward_v": "f8",
    "feedback_v": "f8",
    "adapting": "?",
    "reply_ok": "?",
    "rig_flags": "u1",
    **{f"{name}_hat": "f8" for name in PARAMETER_NAMES},
}


class Trace:
    """Columns of one test, one row per tick.

    Parameters
    ----------
    capacity : int
        Rows to allocate (ticks of the test).
    """

    def __init__(self, capacity: int) -> None:
        self.capacity = capacity
        self.columns = {name: np.zeros(capacity, dtype=dtype) for name, dtype in TRACE_COLUMNS.items()}
        self.rows = 0

    def view(self) -> dict[str, np.ndarray]:
        """The filled part of every column."""
        return {name: col[: self.rows] for name, col in self.columns.items()}


class CanFrameLog:
    """Every frame sent and received, with time and direction.

    Parameters
    ----------
    capacity : int
        Frames to allocate; frames beyond it are counted, not stored.
    """

    def __init__(self, capacity: int) -> None:
        self.capacity = capacity
        self.t_s = np.zeros(capacity)
        self.can_id = np.zeros(capacity, dtype=np.uint16)
        self.dlc = np.zeros(capacity, dtype=np.uint8)
        self._raw = bytearray(capacity * 8)  # payloads, 8 bytes a frame; filled by slice assignment
        self.data = np.frombuffer(self._raw, dtype=np.uint8).reshape(capacity, 8)
        self.rx = np.zeros(capacity, dtype=bool)
        self.count = 0
        self.dropped = 0

    def add(self, t_s: float, can_id: int, data: bytes | bytearray, rx: bool) -> None:
        """Store one frame."""
        n = self.count
        if n >= self.capacity:
            self.dropped += 1
            return
        self.t_s[n] = t_s
        self.can_id[n] = can_id
        length = len(data)
        self.dlc[n] = length
        self._raw[8 * n : 8 * n + length] = data
        self.rx[n] = rx
        self.count = n + 1
