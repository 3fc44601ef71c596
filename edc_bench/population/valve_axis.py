"""The batch path's arrays hold one value per valve along their last axis; a stopped valve's are dropped."""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np


def take_last_axis(owner: object, keep: np.ndarray, names: Iterable[str]) -> None:
    """Keep only the valves ``keep`` (indices, in order) in each named array attribute of ``owner``.

    The result is a new contiguous array, so the next tick's passes over it stay contiguous.
    """
    for name in names:
        setattr(owner, name, np.ascontiguousarray(getattr(owner, name)[..., keep]))


__all__ = ["take_last_axis"]
