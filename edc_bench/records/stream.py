"""The raw CAN log, streamed to disk while a test runs.

The tick only stores frames in the preallocated :class:`CanFrameLog`; a
background thread appends what is new to ``can.log`` (candump format, one line
per frame) every 0.1 s, flushed and fsynced, so a test process that is killed
leaves a log that python-can reads back up to the last 0.1 s. The thread
writes in small batches and yields between them, so it never holds the
interpreter long enough to delay a tick noticeably.
"""

from __future__ import annotations

import os
import threading
import time
from pathlib import Path

from edc_bench.runtime.trace import CanFrameLog

_BATCH = 32


def format_frame(t_s: float, can_id: int, data: bytes, channel: str) -> str:
    """One candump line, as python-can's CanutilsLogWriter writes it."""
    return f"({t_s:f}) {channel} {can_id:03X}#{data.hex().upper()}\n"


class StreamingCanLog:
    """Appends the frames of a :class:`CanFrameLog` to a file as they come.

    Parameters
    ----------
    frames : CanFrameLog
        The log the test fills.
    path : pathlib.Path
        The file (created now).
    period_s : float
        How often new frames are written.
    """

    def __init__(self, frames: CanFrameLog, path: Path, channel: str = "can0", period_s: float = 0.1) -> None:
        self.frames = frames
        self.path = Path(path)
        self.channel = channel
        self.period_s = period_s
        self.written = 0
        self._file = open(self.path, "w", encoding="ascii")  # noqa: SIM115 - closed in stop()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="can-log-writer", daemon=True)

    def __enter__(self) -> StreamingCanLog:
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def _flush_new(self) -> None:
        frames, handle = self.frames, self._file
        end = frames.count
        while self.written < end:
            stop = min(end, self.written + _BATCH)
            lines = [format_frame(float(frames.t_s[k]), int(frames.can_id[k]),
                                  bytes(frames.data[k, : int(frames.dlc[k])]), self.channel)
                     for k in range(self.written, stop)]
            handle.write("".join(lines))
            self.written = stop
            time.sleep(0)  # let the loop run between batches
        handle.flush()
        os.fsync(handle.fileno())

    def _run(self) -> None:
        while not self._stop.wait(self.period_s):
            self._flush_new()

    def stop(self) -> None:
        """Write what is left and close the file."""
        if self._thread.is_alive():
            self._stop.set()
            self._thread.join()
        if not self._file.closed:
            self._flush_new()
            self._file.close()
