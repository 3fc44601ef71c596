"""The per-tick trace as an ASAM MDF 4 file (``trace.mf4``), with the test's CAN frames beside it.

Test engineers in this trade open MDF 4 files in asammdf, CANape or the
Vector tools; this is the format the record's trace is kept in. The file
holds two channel groups on one time base (time 0 is tick 0, the header's
start time is its absolute UTC time):

- ``trace``: one channel per trace column, named as in the trace
  (``position_mm``, ``drive_v``...), each with its unit (``-`` for flags
  and bit fields) and a comment that says what it is; booleans are stored as 0/1;
- ``CAN``: every frame the bench sent and read, as an ASAM bus-logging
  group (``CAN_DataFrame``, direction Tx/Rx), the layout python-can's
  ``MF4Writer`` writes and its ``MF4Reader`` (and asammdf's bus-logging
  tools) read. Frames from before tick 0 (the synchronising SAFE) have
  negative times.

Reading it back gives the trace's columns bit for bit (float64 stays
float64), so reports and replays see what the test saw.
"""

from __future__ import annotations

import datetime as dt
import io
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from edc_bench.errors import ConfigError
from edc_bench.paths import atomic_write

if TYPE_CHECKING:  # only types: writing a file needs nothing of the running loop
    from edc_bench.engine.trace import CanFrameLog

TRACE_GROUP_COMMENT = "edc-bench per-tick trace (time 0: the first tick)"
CAN_GROUP_COMMENT = "edc-bench CAN traffic, bench and rig (Tx: sent by the bench)"

_PARAMETER_UNITS = {"a3": "V s^3/mm", "a2": "V s^2/mm", "a1": "V s/mm", "a0": "V/mm", "b": "V", "af": "V"}

#: unit and comment of every trace column (the time column ``t_s`` is the file's master channel)
CHANNELS: dict[str, tuple[str, str]] = {
    "lateness_s": ("s", "how late the tick began against its schedule"),
    "reply_latency_s": ("s", "time from the command to its reply (NaN: no reply in time)"),
    "reference_mm": ("mm", "rack position reference the loop followed"),
    "reference_velocity_mm_s": ("mm/s", "rack velocity reference"),
    "position_mm": ("mm", "rack position from the rig's LVDT (the sample the tick used)"),
    "current_a": ("A", "coil current from the rig"),
    "drive_v": ("V", "drive command sent to the rig (feedforward + feedback, limited)"),
    "feedforward_v": ("V", "friction-compensated feedforward part of the drive"),
    "feedback_v": ("V", "PID feedback part of the drive"),
    "adapting": ("-", "1 when the estimator learnt on this tick"),
    "reply_ok": ("-", "1 when the tick's reply arrived in time"),
    "rig_flags": ("-", "rig status flags of the newest reply (bit field, see PROTOCOL.md)"),
    "sample_age_ticks": ("tick", "age in ticks of the sample the feedback used (1: its reply came within the tick)"),
    "gap": ("-", "1 when the tick was lost to a host stall (nothing sent, nothing learnt)"),
    "coil_resistance_ohm": ("Ohm", "coil resistance measured so far from drive and current"),
    **{f"{name}_hat": (unit, f"estimate of feedforward parameter {name}")
       for name, unit in _PARAMETER_UNITS.items()},
}


#: channels that are booleans in the trace (stored as 0/1: MDF has no boolean type). Kept here rather than read
#: from the runtime's column list, so a record folder is read with this module alone (another machine's report).
FLAG_CHANNELS = frozenset({"adapting", "reply_ok", "gap"})


def _can_frames(frames: CanFrameLog, time_zero_s: float) -> tuple[np.ndarray, np.ndarray]:
    from edc_bench.canlib import mf4_module

    STD_DTYPE = mf4_module().STD_DTYPE

    n = frames.count
    # data frames only (bits 1 and 2 of the flags: remote, error): can.log keeps those, with their kind
    data_frames = (frames.flags[:n] & 6) == 0
    samples = np.zeros(int(data_frames.sum()), dtype=STD_DTYPE)
    samples["CAN_DataFrame.ID"] = frames.can_id[:n][data_frames]
    samples["CAN_DataFrame.IDE"] = frames.flags[:n][data_frames] & 1
    samples["CAN_DataFrame.DLC"] = frames.dlc[:n][data_frames]
    samples["CAN_DataFrame.DataLength"] = frames.dlc[:n][data_frames]
    samples["CAN_DataFrame.DataBytes"][:, :8] = frames.data[:n][data_frames]
    samples["CAN_DataFrame.Dir"] = np.where(frames.rx[:n][data_frames], 0, 1)  # ASAM: 0 Rx, 1 Tx
    return samples, frames.t_s[:n][data_frames] - time_zero_s


def write_trace_mf4(path: Path, trace: dict[str, np.ndarray], frames: CanFrameLog | None = None, *,
                    ticks_start_s: float = 0.0, origin_unix_s: float = 0.0, comment: str = "") -> None:
    """Write the trace (and the CAN frames) as an MDF 4.10 file, atomically.

    Parameters
    ----------
    path : pathlib.Path
        The ``.mf4`` file.
    trace : dict of numpy.ndarray
        Per-tick columns, ``t_s`` among them.
    frames : CanFrameLog, optional
        The frames to log beside the trace.
    ticks_start_s : float
        Clock time of tick 0 (the frames' times are clock times).
    origin_unix_s : float
        Unix time of clock time 0.
    comment : str
        The file's header comment (variant, valve, verdict).
    """
    from asammdf import MDF, Signal
    from asammdf.blocks.v4_blocks import SourceInformation
    from asammdf.blocks.v4_constants import BUS_TYPE_CAN, SOURCE_BUS

    mdf = MDF(version="4.10")
    try:
        mdf.header.start_time = dt.datetime.fromtimestamp(origin_unix_s + ticks_start_s, tz=dt.UTC)
        mdf.header.comment = comment or "edc-bench bench test"
        t = np.asarray(trace["t_s"], dtype=np.float64)
        signals = []
        for name, values in trace.items():
            if name == "t_s":
                continue
            unit, description = CHANNELS.get(name, ("", name))
            samples = values.astype(np.uint8) if values.dtype == bool else values
            signals.append(Signal(samples, t, name=name, unit=unit, comment=description))
        mdf.append(signals, acq_name="trace", comment=TRACE_GROUP_COMMENT)
        if frames is not None:
            samples, times = _can_frames(frames, ticks_start_s)
            source = SourceInformation(source_type=SOURCE_BUS, bus_type=BUS_TYPE_CAN)
            mdf.append(Signal(samples, times, name="CAN_DataFrame", source=source, comment=CAN_GROUP_COMMENT),
                       acq_name="CAN", comment=CAN_GROUP_COMMENT)
        buffer = io.BytesIO()  # asammdf saves to a path or an in-memory file; the bytes then go down atomically
        mdf.save(buffer, compression=2)
        atomic_write(Path(path), lambda handle: handle.write(buffer.getvalue()))
    finally:
        mdf.close()


def looks_like_mdf4(path: Path) -> bool:
    """True if the file starts as an MDF 4 file does (identification block, then the header block).

    Checked before asammdf parses a file: on some damaged files its parser fails noisily (errors raised from
    its finaliser, the interpreter left in a bad state), so what is plainly not MDF 4 is refused here.
    """
    try:
        with open(path, "rb") as handle:
            head = handle.read(68)
    except OSError:
        return False
    return len(head) == 68 and head[:8] == b"MDF     " and head[8:10] == b"4." and head[64:68] == b"##HD"


def read_trace_mf4(path: Path) -> dict[str, np.ndarray]:
    """The trace columns of a ``trace.mf4`` (``t_s`` from the master channel), in the trace's dtypes."""
    from asammdf import MDF

    path = Path(path)
    if not looks_like_mdf4(path):
        raise ConfigError(f"{path}: not an MDF 4 file")
    try:
        with MDF(str(path)) as mdf:
            group = next((n for n, g in enumerate(mdf.groups) if TRACE_GROUP_COMMENT in str(g.channel_group.comment)),
                         None)
            if group is None:
                raise ConfigError(f"{path}: no edc-bench trace group in this MDF file")
            columns: dict[str, Any] = {}
            names = [ch.name for ch in mdf.groups[group].channels]
            for name in names:
                if name not in CHANNELS:
                    continue
                signal = mdf.get(name, group=group, raw=True)
                columns.setdefault("t_s", np.asarray(signal.timestamps, dtype=np.float64))
                samples = np.asarray(signal.samples)
                columns[name] = samples.astype(bool) if name in FLAG_CHANNELS else samples
    except ConfigError:
        raise
    except Exception as exc:  # noqa: BLE001 - asammdf raises many error types on a damaged file
        raise ConfigError(f"{path}: not a readable MDF trace ({type(exc).__name__}: {exc})") from None
    if "t_s" not in columns:
        raise ConfigError(f"{path}: the trace group has no channels")
    return {"t_s": columns.pop("t_s"), **columns}
