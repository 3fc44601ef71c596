"""What a CAN adapter does to frame timing: latency, jitter and USB frame release.

A USB CAN adapter (slcan/CANable, gs_usb, USB PCAN and Kvaser) moves frames
in USB transfers: a full-speed device is polled once per 1 ms USB frame, so a
frame waits for the next frame boundary in each direction, on top of the
driver's and the bus's own latency. Bench to rig and back then takes 1.5-3.5
ms, where the loop's period is 1 ms.

:class:`AdapterModel` is pure: it maps a send time to a delivery time, one
direction at a time, from a seeded random stream, keeping frames in order (an
adapter is a FIFO). The in-process rig (:mod:`edc_bench.sim.inprocess`),
``edc-bench rig --adapter`` and the batch path use the same model.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TypeAlias

import numpy as np

from edc_bench.errors import ConfigError

ArrayOrFloat: TypeAlias = float | np.ndarray


@dataclass(frozen=True)
class AdapterModel:
    """Timing of one adapter, the same in both directions.

    Attributes
    ----------
    latency_s : float
        Fixed one-way delay (driver, bus transmission).
    jitter_s : float
        Extra one-way delay drawn uniformly from [0, jitter_s) per frame.
    usb_frame_s : float
        If above 0, a frame is delivered only at the next USB frame boundary,
        ``n * usb_frame_s + usb_phase_s`` (a USB full-speed device: 1 ms).
    usb_phase_s : float
        Where the USB frames fall against the bench's ticks at time 0.
    usb_drift_ppm : float
        How much longer a USB frame is than ``usb_frame_s`` (parts per
        million): the host controller's clock is its own, so the frames'
        phase against the bench's ticks walks through a whole frame every
        ``1e6 / usb_drift_ppm`` frames (10 s at 100 ppm), and a test meets
        every phase, as a bench PC's does.
    name : str
        How it was chosen (a preset name or the spec text), for records.
    """

    latency_s: float = 0.0
    jitter_s: float = 0.0
    usb_frame_s: float = 0.0
    usb_phase_s: float = 0.0
    usb_drift_ppm: float = 0.0
    name: str = "none"

    @property
    def is_instant(self) -> bool:
        """True if frames arrive when they are sent (the lockstep default)."""
        return self.latency_s == 0.0 and self.jitter_s == 0.0 and self.usb_frame_s == 0.0

    @property
    def worst_round_trip_s(self) -> float:
        """The longest command-to-reply time this adapter can give (the rig answers at once)."""
        one_way = self.latency_s + self.jitter_s + self.usb_frame_s
        return 2.0 * one_way

    def release_s(self, sent_s: ArrayOrFloat, jitter_s: ArrayOrFloat, previous_s: ArrayOrFloat,
                  usb_phase_s: ArrayOrFloat | None = None) -> ArrayOrFloat:
        """The delivery rule, for floats or numpy arrays alike: latency, the jitter drawn for the frame, the next
        USB frame boundary (at ``usb_phase_s``, the model's own by default), never before ``previous_s``."""
        t = sent_s + self.latency_s + jitter_s
        if self.usb_frame_s > 0.0:
            frame = self.usb_frame_s * (1.0 + 1e-6 * self.usb_drift_ppm)
            phase = self.usb_phase_s if usb_phase_s is None else usb_phase_s
            t = np.ceil((t - phase) / frame - 1e-9) * frame + phase
        return np.maximum(t, previous_s)

    def delivery_s(self, sent_s: float, rng: np.random.Generator, previous_s: float = -math.inf) -> float:
        """When a frame sent at ``sent_s`` comes out at the far end (never before ``previous_s``: in order)."""
        jitter = rng.random() * self.jitter_s if self.jitter_s > 0.0 else 0.0
        return float(self.release_s(sent_s, jitter, previous_s))


#: Named adapters for ``--adapter``.
PRESETS: dict[str, AdapterModel] = {
    "none": AdapterModel(),
    # USB full-speed: 1 ms frames each way, 0.25-0.75 ms of driver, scheduling and bus latency, frames drifting
    # against the ticks at 100 ppm (docs/simulation.md prints the round trip this gives and the replies' age)
    "usb-fs": AdapterModel(latency_s=0.25e-3, jitter_s=0.5e-3, usb_frame_s=1e-3, usb_phase_s=0.37e-3,
                           usb_drift_ppm=100.0, name="usb-fs"),
}


def parse_adapter(text: str) -> AdapterModel:
    """``--adapter``: a preset (``none``, ``usb-fs``) or ``latency_ms=L[,jitter_ms=J][,usb_frame_ms=F][,drift_ppm=D]``.

    Raises
    ------
    ConfigError
        For an unknown preset or key, or a value that is not a non-negative number.
    """
    text = text.strip()
    if text in PRESETS:
        return PRESETS[text]
    keys = {"latency_ms": "latency_s", "jitter_ms": "jitter_s", "usb_frame_ms": "usb_frame_s",
            "drift_ppm": "usb_drift_ppm"}
    values: dict[str, float] = {}
    for part in (p.strip() for p in text.split(",") if p.strip()):
        key, sep, raw = (s.strip() for s in part.partition("="))
        if not sep or key not in keys:
            raise ConfigError(f"--adapter {text!r}: use a preset ({', '.join(PRESETS)}) or "
                              f"latency_ms=L,jitter_ms=J,usb_frame_ms=F (one-way, in ms),drift_ppm=D")
        try:
            value = float(raw)
        except ValueError:
            raise ConfigError(f"--adapter {text!r}: {key} = {raw!r} is not a number") from None
        limit, unit, scale = (1000.0, "ppm", 1.0) if key == "drift_ppm" else (100.0, "ms", 1e-3)
        if not (math.isfinite(value) and 0.0 <= value <= limit):
            raise ConfigError(f"--adapter {text!r}: {key} must lie in 0..{limit:g} {unit}")
        values[keys[key]] = value * scale
    if not values:
        raise ConfigError(f"--adapter {text!r}: give a preset ({', '.join(PRESETS)}) or latency_ms=...")
    return AdapterModel(**values, name=text)
