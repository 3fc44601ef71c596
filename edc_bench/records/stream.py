"""The raw CAN log, written with python-can's candump writer, streamed while a test runs.

The tick only stores frames in the preallocated :class:`CanFrameLog`; a
background thread appends what is new to ``can.log`` every 0.1 s, flushed
and fsynced, so a test process that is killed leaves a log that python-can
reads back up to the last 0.1 s. The thread writes in small batches and
yields between them, so it never holds the interpreter long enough to delay
a tick noticeably.

Lines are python-can's ``CanutilsLogWriter`` format (``candump -L``, with
``R``/``T`` direction marks), with absolute (Unix) timestamps: the frame
log's clock times plus the clock's origin.
"""

from __future__ import annotations

import os
import threading
import time
from pathlib import Path
from typing import TYPE_CHECKING, TextIO

from edc_bench.canlib import can

if TYPE_CHECKING:  # only a type: the CAN log writer needs nothing of the runtime
    from edc_bench.engine.trace import CanFrameLog

_BATCH = 32
CHANNEL = "can0"


def log_frames(writer: can.CanutilsLogWriter, frames: CanFrameLog, start: int, stop: int) -> None:
    """Write frames ``start..stop-1`` of ``frames`` through python-can's writer, with absolute timestamps."""
    origin = frames.origin_unix_s
    for k in range(start, stop):
        dlc = int(frames.dlc[k])
        flags = int(frames.flags[k])
        writer.on_message_received(can.Message(
            timestamp=origin + float(frames.t_s[k]), arbitration_id=int(frames.can_id[k]),
            is_extended_id=bool(flags & 1), is_remote_frame=bool(flags & 2), is_error_frame=bool(flags & 4),
            dlc=dlc, data=bytes(frames.data[k, :dlc]), is_rx=bool(frames.rx[k]), channel=writer.channel,
        ))


def open_log_writer(handle: TextIO) -> can.CanutilsLogWriter:
    """python-can's candump writer on an open text file."""
    return can.CanutilsLogWriter(handle, channel=CHANNEL)


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

    Attributes
    ----------
    complete : bool
        True once :meth:`stop` has written every frame and closed the file.
    error : str or None
        Why streaming stopped early (a full disk, a vanished folder): the file
        then ends where the error struck; the frames are still in memory, and
        the record writes the whole log again when it can. Never raised: a
        full disk must not cost the test or its verdict.
    """

    def __init__(self, frames: CanFrameLog, path: Path, period_s: float = 0.1) -> None:
        self.frames = frames
        self.path = Path(path)
        self.period_s = period_s
        self.written = 0
        self.complete = False
        self.error: str | None = None
        self._file = open(self.path, "w", encoding="ascii")  # noqa: SIM115 - closed in stop()
        self._writer = open_log_writer(self._file)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="can-log-writer", daemon=True)

    def __enter__(self) -> StreamingCanLog:
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def _flush_new(self) -> None:
        end = self.frames.count
        while self.written < end:
            stop = min(end, self.written + _BATCH)
            log_frames(self._writer, self.frames, self.written, stop)
            self.written = stop
            time.sleep(0)  # let the loop run between batches
        self._file.flush()
        os.fsync(self._file.fileno())

    def _flush_or_give_up(self) -> bool:
        """Write what is new; on a write error note it, close the file and return False."""
        try:
            self._flush_new()
        except (OSError, ValueError) as exc:  # ENOSPC, EIO, a file closed under us
            self.error = f"{type(exc).__name__}: {exc}"
            try:
                self._file.close()
            except OSError:
                pass  # closing flushes again, into the same full disk
            return False
        return True

    def _run(self) -> None:
        while not self._stop.wait(self.period_s):
            if not self._flush_or_give_up():
                return

    def stop(self) -> None:
        """Write what is left and close the file (never raises; :attr:`error` says what went wrong)."""
        if self._thread.is_alive():
            self._stop.set()
            self._thread.join()
        if not self._file.closed and self._flush_or_give_up():
            try:
                self._file.close()
                self.complete = True
            except OSError as exc:
                self.error = f"{type(exc).__name__}: {exc}"
