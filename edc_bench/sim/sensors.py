"""Sensor models: offset, Gaussian noise and quantisation, seeded."""

from __future__ import annotations

import numpy as np

from edc_bench.config.models import SensorModel

_BLOCK = 4096


class NoisySensor:
    """A sensor reading ``true + offset + noise``, rounded to its resolution.

    Noise comes from a seeded generator in blocks, so a run is reproducible
    for a given seed and a sample costs no generator call.

    Parameters
    ----------
    model : SensorModel
        Noise standard deviation, resolution and offset (in the sensor's unit).
    rng : numpy.random.Generator
        Source of noise.
    """

    def __init__(self, model: SensorModel, rng: np.random.Generator) -> None:
        self.model = model
        self._rng = rng
        self._noise: list[float] = []
        self._next = 0
        self.stuck_value: float | None = None  # fault injection: a stuck sensor

    def _refill(self) -> None:
        self._noise = (self._rng.standard_normal(_BLOCK) * self.model.noise_sd).tolist()
        self._next = 0

    def sample(self, true_value: float) -> float:
        """One reading of ``true_value``."""
        if self.stuck_value is not None:
            return self.stuck_value
        if self._next >= len(self._noise):
            self._refill()
        noise = self._noise[self._next]
        self._next += 1
        step = self.model.resolution
        return round((true_value + self.model.offset + noise) / step) * step
