"""One ``key=value`` pair of a simulated rig's spec (``--rig-drift``, ``--rack-fault``, ``--sensor-fault``), checked."""

from __future__ import annotations

import math
from collections.abc import Container, Mapping

from edc_bench.errors import ConfigError


def pair_value(given: str, key: str, raw: str, seen: Container[str],
               keys: Mapping[str, tuple[str, float, float]]) -> float:
    """The number of the pair ``key=raw``: given once, a number, within the key's range.

    Parameters
    ----------
    given : str
        How the messages name the input (the flag and its text).
    key, raw : str
        The pair, its key known (one of ``keys``).
    seen : container of str
        The keys given before it.
    keys : mapping
        Each key's (what it is, lowest, highest).

    Raises
    ------
    ConfigError
        One line naming what is wrong and what to give instead.
    """
    if key in seen:
        raise ConfigError(f"{given}: {key} is given twice; give it once")
    what, low, high = keys[key]
    try:
        value = float(raw)
    except ValueError:
        raise ConfigError(f"{given}: {key} = {raw!r} is not a number; give {what}") from None
    if not (math.isfinite(value) and low <= value <= high):
        raise ConfigError(f"{given}: {key} = {raw} is outside {low:g}..{high:g} ({what})")
    return value
