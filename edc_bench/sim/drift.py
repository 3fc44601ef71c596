"""A simulated rig whose sensors have drifted: what the rig self-check must catch (``--rig-drift``).

A real rig's sensors drift with age and handling: an LVDT knocked on its
mounting reads the rack a few hundredths of a millimetre off (its zero),
its excitation or a changed cable scales every reading (its gain), a current
sensor's shunt or Hall element ages (its gain and zero). The bench would
then judge every valve wrongly without a word; the rig self-check
(:mod:`edc_bench.selfcheck`) runs a reference valve to find it. Here the
drift is a property of the simulated rig's sensors, on top of the variant's
own sensor model (its offset, noise and resolution):

    LVDT reading    = lvdt_gain * x + lvdt_offset_mm       (+ the variant's offset and noise)
    current reading = current_gain * i + current_offset_a  (+ the variant's offset and noise)
"""

from __future__ import annotations

from dataclasses import dataclass, fields

from edc_bench.errors import ConfigError
from edc_bench.sim.spec_pairs import pair_value


@dataclass(frozen=True)
class SensorDrift:
    """How far the simulated rig's sensors have drifted from the state the variant describes.

    Attributes
    ----------
    lvdt_offset_mm : float
        Added to every LVDT reading (mm): its zero has moved.
    lvdt_gain : float
        Multiplies the rack position before it is read: its scale has changed (1: none).
    current_gain : float
        Multiplies the coil current before it is read (1: none).
    current_offset_a : float
        Added to every current reading (A): its zero has moved.
    """

    lvdt_offset_mm: float = 0.0
    lvdt_gain: float = 1.0
    current_gain: float = 1.0
    current_offset_a: float = 0.0

    @property
    def none(self) -> bool:
        """True for sensors as the variant describes them."""
        return self == SensorDrift()

    def spec(self) -> str:
        """The ``--rig-drift`` text that gives this drift (``none`` for none)."""
        default = SensorDrift()
        parts = [f"{f.name}={getattr(self, f.name):g}" for f in fields(self)
                 if getattr(self, f.name) != getattr(default, f.name)]
        return ",".join(parts) or "none"


#: Each key ``--rig-drift`` takes: (what it is, lowest, highest), the range generous but physical.
KEYS: dict[str, tuple[str, float, float]] = {
    "lvdt_offset_mm": ("the LVDT's zero shift in mm", -2.0, 2.0),
    "lvdt_gain": ("the LVDT's scale, 1 for none", 0.5, 1.5),
    "current_gain": ("the current sensor's scale, 1 for none", 0.5, 1.5),
    "current_offset_a": ("the current sensor's zero shift in A", -1.0, 1.0),
}

EXAMPLE = "lvdt_offset_mm=0.05 or current_gain=1.03 (keys: " + ", ".join(KEYS) + ")"


def parse_rig_drift(text: str, flag: str = "--rig-drift") -> SensorDrift:
    """``--rig-drift``: ``none`` or ``key=value`` pairs separated by commas (:data:`KEYS`).

    Parameters
    ----------
    text : str
        E.g. ``lvdt_offset_mm=0.05,current_gain=1.03``.
    flag : str, optional
        How the messages name the input (``--rig-drift``; empty: the text alone, for argparse, which names the
        flag itself).

    Returns
    -------
    SensorDrift

    Raises
    ------
    ConfigError
        One line naming the part that is wrong and what to give instead.
    """
    given = f"{flag} {text!r}" if flag else repr(text)
    text = text.strip()
    if text in ("", "none"):
        return SensorDrift()
    values: dict[str, float] = {}
    for part in (p.strip() for p in text.split(",")):
        key, sep, raw = (s.strip() for s in part.partition("="))
        if not sep or key not in KEYS:
            what = given if part == text else f"{given}: {part!r}"
            raise ConfigError(f"{what} is not a drift; give key=value pairs such as {EXAMPLE}")
        values[key] = pair_value(given, key, raw, values, KEYS)
    return SensorDrift(**values)
