"""The self-check's judgement: each figure against its registration, the drifts named, GO or NO-GO (pure).

A figure is out when it moved beyond its tolerance (the variant's ``[selfcheck]``
section: absolute for the two zeros, relative for the rest). The drifts are
then named by their cause, from the pattern of what moved, since each sensor
moves its own figures (:mod:`edc_bench.selfcheck.measure`):

- the LVDT's zero: the rest position alone;
- the current sensor's zero: the rest current (and a little the coil's resistance);
- the current sensor's gain: the coil's resistance alone;
- the LVDT's gain: the spring rate a0, and a1 with it by the same share (both are per mm of the LVDT's reading);
- the drive (the amplifier's gain, or a coil warmer than stated): af, a0 and a1 by the same share;
- the reference valve or the rig's mechanics: af or a1 alone.

A figure that moved with its cause (a1 with the LVDT's gain) is listed as moved and explained, and the verdict
names the cause once. A reference test that is not to be trusted (INVALID) is a NO-GO of its own: its figures
are not compared.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass, field

#: The figures a self-check compares, in the order they are shown.
QUANTITIES = ("lvdt_zero_mm", "current_zero_a", "coil_r20_ohm", "a0_v_per_mm", "af_v", "a1_v_s_per_mm")
#: The figures read at rest (compared even when the reference test is not to be trusted), compared in absolute
#: terms; the others are compared relative to their registration.
REST_QUANTITIES = ("lvdt_zero_mm", "current_zero_a")


@dataclass(frozen=True)
class ReferenceValues:
    """What the reference valve and the rig at rest measured (:mod:`edc_bench.selfcheck.measure`).

    Attributes
    ----------
    lvdt_zero_mm : float
        The rack position read at rest, no drive (mm): the LVDT's zero.
    current_zero_a : float
        The coil current read at rest, no drive (A): the current sensor's zero.
    coil_r20_ohm : float
        The coil's resistance measured in the test, referred to 20 degC (ohm).
    a0_v_per_mm : float
        The spring rate identified, in volts per mm of the LVDT's reading, at 20 degC.
    af_v : float
        The reference valve's friction in volts, at 20 degC.
    a1_v_s_per_mm : float
        The reference valve's damping in V s/mm, at 20 degC.
    lvdt_at_floor : bool
        The LVDT read 0 mm or less at rest (the frame carries no less): ``lvdt_zero_mm`` is an upper bound.
    test_problems : tuple of str
        Why the reference test is not to be trusted (empty: it is).
    coil_temp_c : float
        The coil's temperature at the start of the test, as stated (20 degC: a rested coil).
    signal_faults : tuple of str
        What the LVDT's own signal showed beyond the part diagnosis's limits (its noise, spikes, dropouts: the same
        signatures a pump's test judges its rack-travel sensor by), in a few words each; empty: a clean signal.
    """

    lvdt_zero_mm: float
    current_zero_a: float
    coil_r20_ohm: float
    a0_v_per_mm: float
    af_v: float
    a1_v_s_per_mm: float
    lvdt_at_floor: bool = False
    test_problems: tuple[str, ...] = ()
    coil_temp_c: float = 20.0
    signal_faults: tuple[str, ...] = ()

    def figures(self) -> dict[str, float]:
        """The compared figures by name (:data:`QUANTITIES`)."""
        return {name: getattr(self, name) for name in QUANTITIES}


@dataclass(frozen=True)
class Tolerances:
    """How far each figure may move from its registration before the self-check is NO-GO.

    Attributes
    ----------
    lvdt_zero_mm : float
        The rest position (mm, absolute).
    current_zero_a : float
        The rest current (A, absolute).
    coil_r20_rel, a0_rel, af_rel, a1_rel : float
        The coil's resistance, the spring rate, af and a1 (relative: 0.015 is 1.5 %).
    """

    lvdt_zero_mm: float = 0.02
    current_zero_a: float = 0.01
    coil_r20_rel: float = 0.015
    a0_rel: float = 0.015
    af_rel: float = 0.02
    a1_rel: float = 0.02

    def of(self, quantity: str) -> float:
        """The tolerance of ``quantity`` (a name of :data:`QUANTITIES`)."""
        return {"lvdt_zero_mm": self.lvdt_zero_mm, "current_zero_a": self.current_zero_a,
                "coil_r20_ohm": self.coil_r20_rel, "a0_v_per_mm": self.a0_rel, "af_v": self.af_rel,
                "a1_v_s_per_mm": self.a1_rel}[quantity]


class Cause(enum.StrEnum):
    """What drifted, named for the technician."""

    LVDT_ZERO = "LVDT zero"
    CURRENT_ZERO = "current sensor zero"
    CURRENT_GAIN = "current sensor gain"
    LVDT_GAIN = "LVDT gain"
    DRIVE = "drive gain"
    VALVE = "reference valve or rig mechanics"
    TEST = "reference test not trustworthy"
    LVDT_SIGNAL = "LVDT signal"


#: Each figure's name in the technician's words and its unit (None: compared in %).
LABELS: dict[str, tuple[str, str | None]] = {
    "lvdt_zero_mm": ("LVDT zero", "mm"),
    "current_zero_a": ("current zero", "A"),
    "coil_r20_ohm": ("coil resistance", None),
    "a0_v_per_mm": ("spring rate a0", None),
    "af_v": ("friction af", None),
    "a1_v_s_per_mm": ("damping a1", None),
}


@dataclass(frozen=True)
class QuantityCheck:
    """One figure against its registration.

    Attributes
    ----------
    name : str
        Its name (:data:`QUANTITIES`).
    measured, registered : float
        Now and at registration.
    drift : float
        ``measured - registered`` for the zeros (mm, A), ``measured / registered - 1`` for the rest; NaN when
        not compared.
    tolerance : float
        How far it may move (the same unit as ``drift``).
    out : bool
        It moved beyond its tolerance.
    compared : bool
        False when the reference test was not trustworthy (a figure of the test) or the figure is missing.
    explained_by : Cause or None
        The cause it moved with, named once in the verdict (a1 with the LVDT's gain).
    """

    name: str
    measured: float
    registered: float
    drift: float
    tolerance: float
    out: bool
    compared: bool = True
    explained_by: Cause | None = None

    @property
    def relative(self) -> bool:
        """Compared relative to its registration (the zeros are compared in mm and A)."""
        return self.name not in REST_QUANTITIES

    def drift_text(self) -> str:
        """``+0.050 mm`` or ``-2.9 %``; ``not compared``."""
        if not self.compared or not math.isfinite(self.drift):
            return "not compared"
        if self.relative:
            return f"{self.drift * 100:+.1f} %"
        return f"{self.drift:+.3f} mm" if self.name == "lvdt_zero_mm" else f"{self.drift:+.4f} A"

    def limit_text(self) -> str:
        """``0.02 mm`` or ``1.5 %``."""
        return f"{self.tolerance * 100:g} %" if self.relative else f"{self.tolerance:g} {LABELS[self.name][1]}"


@dataclass(frozen=True)
class DriftFinding:
    """One drift named: its cause and the words for the technician (what moved, the limit, what to do)."""

    cause: Cause
    words: str


@dataclass(frozen=True)
class SelfCheckResult:
    """A rig self-check: GO or NO-GO, each figure against its registration, and the drifts named.

    Attributes
    ----------
    quantities : tuple of QuantityCheck
        Every figure, in the order of :data:`QUANTITIES`.
    findings : tuple of DriftFinding
        The drifts named (empty for GO).
    """

    quantities: tuple[QuantityCheck, ...]
    findings: tuple[DriftFinding, ...] = field(default_factory=tuple)

    @property
    def go(self) -> bool:
        """GO: nothing drifted."""
        return not self.findings

    @property
    def verdict(self) -> str:
        """``GO`` or ``NO-GO``."""
        return "GO" if self.go else "NO-GO"

    @property
    def causes(self) -> tuple[Cause, ...]:
        """What drifted, in the order named."""
        return tuple(f.cause for f in self.findings)

    @property
    def drifted(self) -> tuple[str, ...]:
        """The figures that moved beyond their tolerance."""
        return tuple(q.name for q in self.quantities if q.out)

    def quantity(self, name: str) -> QuantityCheck:
        """The check of figure ``name``."""
        return next(q for q in self.quantities if q.name == name)

    def line(self) -> str:
        """The technician's line: ``rig self-check: GO`` or ``rig self-check: NO-GO: <what moved, the limit, what to
        do>`` (each drift, separated by ``; ``)."""
        if self.go:
            return "rig self-check: GO"
        return "rig self-check: NO-GO: " + "; ".join(f.words for f in self.findings)


def _check(name: str, measured: float, registered: float, tolerance: float, compared: bool) -> QuantityCheck:
    relative = name not in REST_QUANTITIES
    ok = compared and math.isfinite(measured) and math.isfinite(registered) and (registered != 0 or not relative)
    if not ok:
        return QuantityCheck(name, measured, registered, math.nan, tolerance, False, compared=False)
    drift = measured / registered - 1.0 if relative else measured - registered
    return QuantityCheck(name, measured, registered, drift, tolerance, abs(drift) > tolerance)


_AGAIN = "then run the self-check again"


def compare(measured: ReferenceValues, registered: ReferenceValues, tolerances: Tolerances) -> SelfCheckResult:
    """Judge a self-check: each figure against its registration, the drifts named by their cause.

    Parameters
    ----------
    measured : ReferenceValues
        The reference valve and the rig at rest now.
    registered : ReferenceValues
        The same when the reference valve was registered.
    tolerances : Tolerances
        How far each figure may move (the variant's ``[selfcheck]`` section).

    Returns
    -------
    SelfCheckResult
        GO when no figure moved beyond its tolerance, the reference test was trustworthy and the LVDT's signal clean.
    """
    trusted = not measured.test_problems
    # figures read through a signal that spikes, drops out or is noisy say nothing of the valve or the rig's gains
    readable = trusted and not measured.signal_faults
    checks = {name: _check(name, getattr(measured, name), getattr(registered, name), tolerances.of(name),
                           readable or name in REST_QUANTITIES) for name in QUANTITIES}
    findings: list[DriftFinding] = []
    if measured.signal_faults:  # the signal itself, before any figure read from it
        findings.append(DriftFinding(Cause.LVDT_SIGNAL, "the LVDT's signal is not clean (" + ", ".join(
            measured.signal_faults) + "): check the LVDT, its cable and its connector, " + _AGAIN))
    if trusted is False:
        findings.append(DriftFinding(Cause.TEST, "the reference test was not trustworthy (" + "; ".join(
            measured.test_problems[:2]) + "): check the reference valve's mounting and the rig as the reasons say, "
            + _AGAIN))

    zero = checks["lvdt_zero_mm"]
    if measured.lvdt_at_floor and not registered.lvdt_at_floor:
        # the frame carries no negative position: the zero is somewhere at or below 0 mm
        drift = 0.0 - registered.lvdt_zero_mm
        checks["lvdt_zero_mm"] = zero = QuantityCheck(zero.name, zero.measured, zero.registered, drift,
                                                      zero.tolerance, True)
        findings.append(DriftFinding(Cause.LVDT_ZERO, f"LVDT zero moved down to 0.000 mm or below (registered "
                                f"{registered.lvdt_zero_mm:.3f} mm, limit {zero.limit_text()}; the rig reports no "
                                f"less than 0 mm): check the LVDT's mounting and zero it, {_AGAIN}"))
    elif zero.out:
        findings.append(DriftFinding(Cause.LVDT_ZERO, f"LVDT zero moved {zero.drift_text()} (limit {zero.limit_text()}): "
                                f"check the LVDT's mounting and zero it, {_AGAIN}"))
    current_zero = checks["current_zero_a"]
    if current_zero.out:
        findings.append(DriftFinding(Cause.CURRENT_ZERO, f"current sensor zero moved {current_zero.drift_text()} (limit "
                                f"{current_zero.limit_text()}): zero the current sensor (its offset adjustment), "
                                + _AGAIN))

    coil, a0, af, a1 = (checks[n] for n in ("coil_r20_ohm", "a0_v_per_mm", "af_v", "a1_v_s_per_mm"))
    if coil.out:
        findings.append(DriftFinding(Cause.CURRENT_GAIN, f"coil resistance measured {coil.drift_text()} (limit "
                                f"{coil.limit_text()}): the current sensor's gain has changed (or the reference "
                                f"valve's coil is warmer than stated: let it rest); calibrate the current sensor "
                                f"against a reference shunt, {_AGAIN}"))

    def together(a: QuantityCheck, b: QuantityCheck) -> bool:
        """``b`` moved by the share ``a`` did, within ``b``'s tolerance."""
        return a.compared and b.compared and abs(b.drift - a.drift) <= b.tolerance

    if a0.out and af.out and together(a0, af):
        # every figure in volts moved alike: the drive, not a sensor
        explained = ["af_v", "a0_v_per_mm"] + (["a1_v_s_per_mm"] if a1.out and together(a0, a1) else [])
        for name in explained:
            checks[name] = _explained(checks[name], Cause.DRIVE)
        findings.append(DriftFinding(Cause.DRIVE, f"friction af, spring rate a0{' and damping a1' if len(explained) > 2 else ''} "
                                f"moved alike, {a0.drift_text()} (limit {a0.limit_text()}): the drive amplifier's gain "
                                f"or the supply has changed, or the reference valve's coil is warmer than stated (let "
                                f"it rest); check the amplifier against a voltmeter, {_AGAIN}"))
    elif a0.out:
        checks["a0_v_per_mm"] = _explained(a0, Cause.LVDT_GAIN)
        moved_with = a1.out and together(a0, a1)
        if moved_with:
            checks["a1_v_s_per_mm"] = _explained(a1, Cause.LVDT_GAIN)
        findings.append(DriftFinding(Cause.LVDT_GAIN, f"LVDT gain changed: the spring rate measured moved "
                                f"{a0.drift_text()}{' and damping a1 with it' if moved_with else ''} (limit "
                                f"{a0.limit_text()}): calibrate the LVDT's scale against gauge blocks, {_AGAIN}"))
    valve = [checks[n] for n in ("af_v", "a1_v_s_per_mm") if checks[n].out and checks[n].explained_by is None]
    if valve:
        what = " and ".join(f"{LABELS[q.name][0]} {q.drift_text()} (limit {q.limit_text()})" for q in valve)
        findings.append(DriftFinding(Cause.VALVE, f"the reference valve measures differently: {what}: check its "
                                "mounting and the rig's mechanics (rack guides, lubrication); if the reference valve "
                                f"itself has changed, an engineer registers it again; {_AGAIN}"))
    return SelfCheckResult(tuple(checks[n] for n in QUANTITIES), tuple(findings))


def _explained(check: QuantityCheck, cause: Cause) -> QuantityCheck:
    from dataclasses import replace

    return replace(check, explained_by=cause)


__all__ = ["LABELS", "QUANTITIES", "Cause", "DriftFinding", "QuantityCheck", "ReferenceValues", "SelfCheckResult",
           "Tolerances", "compare"]
