"""Per-tick trace and raw CAN frames, in preallocated arrays.

The tick writes into arrays sized before the test, so recording allocates
nothing per tick; what was measured up to an abort is all there.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from edc_bench.config.models import PARAMETER_NAMES

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
    "sample_age_ticks": "u1",  # age of the sample the tick's feedback used (1: its reply came within the tick)
    "gap": "?",  # the tick was lost to a host stall: nothing was sent, nothing learnt
    "coil_resistance_ohm": "f8",  # the coil's resistance measured so far (from drive and current)
    **{f"{name}_hat": "f8" for name in PARAMETER_NAMES},
}

# the order :meth:`Trace.write_tick` fills them in
_TICK_COLUMNS = ("t_s", "lateness_s", "reply_latency_s", "reference_mm", "reference_velocity_mm_s", "position_mm",
                 "current_a", "drive_v", "feedforward_v", "feedback_v", "adapting", "reply_ok", "rig_flags",
                 "sample_age_ticks", "coil_resistance_ohm")


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
        self._cols = [self.columns[name] for name in _TICK_COLUMNS]
        self._parameter_columns = [self.columns[f"{name}_hat"] for name in PARAMETER_NAMES]

    def write_tick(self, k: int, t_s: float, lateness_s: float, reply_latency_s: float, controller: Any,
                   position_mm: float, current_a: float, drive_v: float, reply_ok: bool, rig_flags: int,
                   sample_age_ticks: int = 1) -> None:
        """Store tick ``k``: its timing, the controller's last step and what the rig reported.

        The one place a tick becomes a trace row, for the live loop and for replay. The rig's
        figures are the newest known when the tick ran; :meth:`reply_arrived` puts the tick's
        own sample in its row once the reply to its command comes.
        """
        c = self._cols
        c[0][k] = t_s
        c[1][k] = lateness_s
        c[2][k] = reply_latency_s
        c[3][k] = controller.reference_mm
        c[4][k] = controller.reference_velocity_mm_s
        c[5][k] = position_mm
        c[6][k] = current_a
        c[7][k] = drive_v
        c[8][k] = controller.feedforward_v
        c[9][k] = controller.feedback_v
        c[10][k] = controller.adapting
        c[11][k] = reply_ok
        c[12][k] = rig_flags
        c[13][k] = min(sample_age_ticks, 255)
        c[14][k] = controller.coil_resistance_ohm
        controller.write_parameters(self._parameter_columns, k)
        self.rows = k + 1

    def reply_arrived(self, k: int, reply_latency_s: float, position_mm: float, current_a: float,
                      rig_flags: int) -> None:
        """The reply to tick ``k``'s command came: its sample belongs in row ``k``."""
        c = self._cols
        c[2][k] = reply_latency_s
        c[5][k] = position_mm
        c[6][k] = current_a
        c[11][k] = True
        c[12][k] = rig_flags

    def write_gap(self, k: int, t_s: float, controller: Any) -> None:
        """Tick ``k`` was lost to a host stall: a row that says so, holding the last figures."""
        c = self._cols
        last = k - 1
        for col in c:
            col[k] = col[last] if last >= 0 else 0
        c[0][k] = t_s
        c[1][k] = float("nan")  # never ran: no lateness
        c[2][k] = float("nan")
        c[10][k] = False
        c[11][k] = False
        self.columns["gap"][k] = True
        controller.write_parameters(self._parameter_columns, k)
        self.rows = k + 1

    def view(self) -> dict[str, np.ndarray]:
        """The filled part of every column."""
        return {name: col[: self.rows] for name, col in self.columns.items()}


#: bits of :attr:`CanFrameLog.flags`
FRAME_EXTENDED, FRAME_REMOTE, FRAME_ERROR, FRAME_TRUNCATED = 1, 2, 4, 8


def frame_flags(msg: Any) -> int:
    """The :attr:`CanFrameLog.flags` of a python-can message (0 for a classic standard data frame)."""
    return (msg.is_extended_id * FRAME_EXTENDED | msg.is_remote_frame * FRAME_REMOTE
            | msg.is_error_frame * FRAME_ERROR | (len(msg.data) > 8) * FRAME_TRUNCATED)


class CanFrameLog:
    """Every frame sent and received, with time, direction and kind.

    Allocated once, before the test, for ``capacity`` frames: enough for
    what the loop can read at most (its frame budget at every read), so even a
    hostile bus's frames are all logged. The arrays are zero-filled by the
    operating system on first touch, so the memory a test really uses is what
    its frames fill. Frames beyond ``capacity`` are counted in :attr:`dropped`,
    not stored (the record says how many).

    Parameters
    ----------
    capacity : int
        Frames to allocate.
    """

    def __init__(self, capacity: int) -> None:
        self.capacity = capacity
        self.t_s = np.zeros(capacity)
        self.can_id = np.zeros(capacity, dtype=np.uint32)  # 29-bit extended ids too
        self.dlc = np.zeros(capacity, dtype=np.uint8)
        self.data = np.zeros((capacity, 8), dtype=np.uint8)
        self._raw = self.data.data.cast("B")  # payloads, 8 bytes a frame; filled by slice assignment
        self.rx = np.zeros(capacity, dtype=bool)
        self.flags = np.zeros(capacity, dtype=np.uint8)  # FRAME_EXTENDED | FRAME_REMOTE | FRAME_ERROR | FRAME_TRUNCATED
        self.count = 0
        self.dropped = 0
        #: Unix time of clock time 0, so logs carry absolute timestamps (set by the loop when its clock starts)
        self.origin_unix_s = 0.0

    def add(self, t_s: float, can_id: int, data: bytes | bytearray, rx: bool, flags: int = 0,
            dlc: int | None = None) -> None:
        """Store one frame.

        A payload beyond 8 bytes (CAN FD) is cut to 8 and flagged FRAME_TRUNCATED; ``dlc`` is a remote
        frame's DLC (it has no payload).
        """
        n = self.count
        if n >= self.capacity:
            self.dropped += 1
            return
        self.t_s[n] = t_s
        self.can_id[n] = can_id
        length = len(data)
        if length > 8:
            data, length, flags = data[:8], 8, flags | FRAME_TRUNCATED
        self._raw[8 * n : 8 * n + length] = data
        self.dlc[n] = length if dlc is None or length else min(dlc, 8)
        self.rx[n] = rx
        self.flags[n] = flags
        self.count = n + 1
