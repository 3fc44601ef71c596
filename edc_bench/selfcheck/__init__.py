"""The rig self-check with a reference valve, and its ledger (``edc-bench rig-selfcheck``, docs/faults.md).

A shop keeps one known valve at each bench. When it is registered, the bench
reads the rig at rest (the LVDT's zero, the current sensor's zero) and tests
the valve, and the history keeps the figures (:class:`Registration`). A
self-check does the same again and compares (:func:`run_selfcheck`): GO, or
NO-GO naming what drifted and what to do. Every check goes into the history,
the ledger ``edc-bench history --rig`` shows; a variant may ask for a check
every N tests or hours, which :func:`~edc_bench.selfcheck.due.selfcheck_due`
tells a session.

The parts:

- :mod:`~edc_bench.selfcheck.compare`: the figures against their registration, the drifts named (pure);
- :mod:`~edc_bench.selfcheck.due`: when a check is due (pure);
- :mod:`~edc_bench.selfcheck.rest` and :mod:`~edc_bench.selfcheck.measure`: measuring, on a rig's bus or on the
  simulated rig;
- this module: the functions a command or a session calls, and the history's rows.

A session calls, with the station's history open as ``store``::

    registration = Registration.of(store.reference(station))   # None: say no_reference_line(station) once
    if registration is not None:
        variant = load_variant(registration.variant)
        why = check_due(store, registration, SelfCheckPolicy.of_variant(variant), now)  # at the start: always run
        check = run_selfcheck(rig, registration, variant)
        store.add_rig_check(rig_check_row(check, station, by))
        print(check.result.line())                              # GO, or NO-GO: what drifted, what to do
"""

from __future__ import annotations

import datetime as dt
import json
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from edc_bench.config.models import Variant
from edc_bench.selfcheck.compare import (
    QUANTITIES,
    Cause,
    ReferenceValues,
    SelfCheckResult,
    Tolerances,
    compare,
)
from edc_bench.selfcheck.due import LastCheck, SelfCheckPolicy, selfcheck_due

if TYPE_CHECKING:
    from edc_bench.history.rows import ReferenceRow, RigCheckRow
    from edc_bench.runtime.bus_config import BusSettings

#: Exactly how the reference valve is registered, for the line that says none is.
REGISTER_COMMAND = "edc-bench rig-selfcheck --register --valve-id ID"


@dataclass(frozen=True)
class Rig:
    """The rig a self-check runs on.

    Attributes
    ----------
    bus : BusSettings or None
        python-can settings (``interface``, ``channel``, ``bitrate``) of a rig's bus; None: the simulated rig in
        process, in simulated time.
    drift : SensorDrift or None
        The simulated rig only: its sensors' drift (``--rig-drift``).
    firmware : str
        The simulated rig only: its firmware (``python`` or ``c``).
    """

    bus: BusSettings | None = None
    drift: Any = None
    firmware: str = "python"

    @property
    def simulated(self) -> bool:
        """True for the simulated rig."""
        return self.bus is None

    def describe(self) -> str:
        """The rig in a few words."""
        if self.bus is not None:
            return "bus " + ", ".join(f"{k}={v}" for k, v in self.bus.items())
        drift = "" if self.drift is None or self.drift.none else f", sensors drifted: {self.drift.spec()}"
        return f"simulated rig ({self.firmware} firmware), simulated time{drift}"


@dataclass(frozen=True)
class Registration:
    """A station's reference valve as registered (a row of the history's ``reference_valves``).

    Attributes
    ----------
    id : int or None
        Its row (None before it is stored).
    station, valve_id, variant : str
        Where, which valve, and the variant it is tested as.
    values : ReferenceValues
        Its figures when registered.
    simulated : bool
        Registered on the simulated rig.
    valve_spec : str or None
        The simulated valve (``new``), on the simulated rig.
    seed : int or None
        The simulated rig's noise seed it was registered with.
    registered_at : str
        When (ISO, UTC).
    """

    id: int | None
    station: str
    valve_id: str
    variant: str
    values: ReferenceValues
    simulated: bool
    valve_spec: str | None = None
    seed: int | None = None
    registered_at: str = ""

    @classmethod
    def of(cls, row: ReferenceRow | None) -> Registration | None:
        """The registration a history row holds (None for None)."""
        if row is None:
            return None
        details = json.loads(row.details or "{}")
        return cls(id=row.id, station=row.station, valve_id=row.valve_id, variant=row.variant,
                   values=values_of(row), simulated=bool(row.simulated), valve_spec=row.valve_spec,
                   seed=details.get("seed"), registered_at=row.registered_at or "")


@dataclass(frozen=True)
class SelfCheck:
    """One rig self-check: the judgement, what was measured, and against which registration.

    Attributes
    ----------
    result : SelfCheckResult
        GO or NO-GO, each figure against its registration, the drifts named; ``result.line()`` is the
        technician's line.
    measured : ReferenceValues
        The figures now.
    registration : Registration
        What they were compared with.
    details : dict
        How it was measured (the rig, the seed and drift of the simulated rig).
    simulated : bool
        It ran on the simulated rig.
    """

    result: SelfCheckResult
    measured: ReferenceValues
    registration: Registration
    details: dict[str, Any] = field(default_factory=dict)
    simulated: bool = False


def tolerances_of(variant: Variant) -> Tolerances:
    """The self-check's tolerances a variant's ``[selfcheck]`` section states."""
    s = variant.selfcheck
    return Tolerances(lvdt_zero_mm=s.lvdt_zero_mm, current_zero_a=s.current_zero_a, coil_r20_rel=s.coil_r20_rel,
                      a0_rel=s.a0_rel, af_rel=s.af_rel, a1_rel=s.a1_rel)


def measure_reference(rig: Rig, variant: Variant, *, valve: str = "new", seed: int = 0, valve_id: str = "",
                      coil_temp_c: float | None = None, observer: Any = None) -> ReferenceValues:
    """Measure the reference valve on ``rig``: the rig at rest, then its bench test (about 31 s on a rig).

    Parameters
    ----------
    rig : Rig
        A rig's bus, or the simulated rig.
    variant : Variant
        The reference valve's variant.
    valve : str, optional
        The simulated rig only: the simulated reference valve (``new``, or physical values).
    seed : int, optional
        The simulated rig only: its sensor noise's seed.
    valve_id : str, optional
        The reference valve's id, for the test.
    coil_temp_c : float, optional
        The coil's temperature at the start (20 degC, a rested coil, if not given).
    observer : LoopObserver, optional
        Shown the test as it runs.

    Returns
    -------
    ReferenceValues

    Raises
    ------
    RigError
        The bus could not be opened, or the rig did not report READY or answer at rest.
    """
    from edc_bench.selfcheck.measure import measure_on_bus, measure_simulated

    if rig.bus is None:
        values, _ = measure_simulated(variant, valve, seed, drift=rig.drift, firmware=rig.firmware, valve_id=valve_id,
                                      coil_temp_c=coil_temp_c, observer=observer)
        return values
    from edc_bench.protocol import default_icd
    from edc_bench.runtime.bus import ClosingBus, open_bus
    from edc_bench.runtime.clock import RealTimeClock

    with ClosingBus(open_bus(rig.bus, default_icd().bitrate)) as bus:
        values, _ = measure_on_bus(bus, RealTimeClock, variant, valve_id=valve_id, coil_temp_c=coil_temp_c,
                                   observer=observer)
    return values


def run_selfcheck(rig: Rig, registration: Registration, variant: Variant, *, seed: int = 1,
                  valve: str | None = None, coil_temp_c: float | None = None, observer: Any = None) -> SelfCheck:
    """Run the rig self-check: measure the reference valve again and compare with its registration.

    Parameters
    ----------
    rig : Rig
        The rig (a bus, or the simulated rig).
    registration : Registration
        The station's reference valve (``Registration.of(store.reference(station))``).
    variant : Variant
        The registration's variant (its ``[selfcheck]`` tolerances).
    seed : int, optional
        The simulated rig only: the noise's seed (another than the registration's, as a new day's noise is).
    valve : str, optional
        The simulated rig only: the valve fitted (default: the one registered).
    coil_temp_c : float, optional
        The reference coil's temperature at the start (20 degC, a rested coil, if not given).
    observer : LoopObserver, optional
        Shown the test as it runs.

    Returns
    -------
    SelfCheck
        ``check.result.go``, ``check.result.line()`` (the technician's line); store it with
        :func:`rig_check_row`.
    """
    fitted = valve or registration.valve_spec or "new"
    measured = measure_reference(rig, variant, valve=fitted, seed=seed, valve_id=registration.valve_id,
                                 coil_temp_c=coil_temp_c, observer=observer)
    result = compare(measured, registration.values, tolerances_of(variant))
    details: dict[str, Any] = {"rig": rig.describe()}
    if rig.simulated:
        details.update(seed=seed, valve=fitted, drift=None if rig.drift is None else rig.drift.spec())
    return SelfCheck(result, measured, registration, details, rig.simulated)


def no_reference_line(station: str) -> str:
    """What to say where a station has no reference valve: once, and the test goes on."""
    return (f"rig self-check: no reference valve is registered for station {station!r}: keep one known valve at the "
            f"bench and register it ({REGISTER_COMMAND}, an engineer's login on a shop's history); until then the "
            "rig's sensors are not checked")


def values_of(row: ReferenceRow | RigCheckRow) -> ReferenceValues:
    """The figures a ``reference_valves`` or ``rig_checks`` row holds."""
    details = json.loads(row.details or "{}")
    figures = row.figures()
    return ReferenceValues(**{name: _float(figures[name]) for name in QUANTITIES},
                           lvdt_at_floor=bool(row.lvdt_at_floor), test_problems=tuple(details.get("test_problems", ())),
                           coil_temp_c=_float(row.coil_temp_c if row.coil_temp_c is not None else 20.0),
                           signal_faults=tuple(details.get("signal_faults", ())))


def _float(value: Any) -> float:
    return float("nan") if value is None else float(value)


def _figures_row(values: ReferenceValues) -> dict[str, Any]:
    import math

    return {**{name: (v if math.isfinite(v) else None) for name, v in values.figures().items()},
            "lvdt_at_floor": values.lvdt_at_floor, "coil_temp_c": values.coil_temp_c}


def registration_row(values: ReferenceValues, *, station: str, valve_id: str, variant: str, by: str,
                     simulated: bool, valve_spec: str | None = None, details: dict[str, Any] | None = None
                     ) -> dict[str, Any]:
    """The history row of a registration (:meth:`~edc_bench.history.store.HistoryStore.add_reference`)."""
    from edc_bench import __version__

    return {"station": station, "valve_id": valve_id, "variant": variant, **_figures_row(values),
            "simulated": simulated, "valve_spec": valve_spec if simulated else None,
            "details": json.dumps({**(details or {}), "test_problems": list(values.test_problems),
                                   **({"signal_faults": list(values.signal_faults)} if values.signal_faults else {})},
                                  sort_keys=True),
            "software_version": __version__, "registered_by": by}


def rig_check_row(check: SelfCheck, station: str, by: str) -> dict[str, Any]:
    """The history row of a self-check (:meth:`~edc_bench.history.store.HistoryStore.add_rig_check`)."""
    from edc_bench import __version__

    result = check.result
    figures = {q.name: {"measured": _json_float(q.measured), "registered": _json_float(q.registered),
                        "drift": _json_float(q.drift), "tolerance": q.tolerance, "out": q.out, "compared": q.compared,
                        "explained_by": None if q.explained_by is None else str(q.explained_by)}
               for q in result.quantities}
    details = {**check.details, "figures": figures, "test_problems": list(check.measured.test_problems),
               **({"signal_faults": list(check.measured.signal_faults)} if check.measured.signal_faults else {})}
    return {"station": station, "reference_id": check.registration.id, "verdict": result.verdict,
            "causes": ",".join(str(c) for c in result.causes), "words": result.line(),
            **_figures_row(check.measured), "simulated": check.simulated,
            "details": json.dumps(details, sort_keys=True), "software_version": __version__,
            "checked_by": by}


#: the ``verdict`` of a ledger row that records a due self-check the technician skipped (Esc), not a measurement
SKIPPED = "SKIPPED"
#: the verdicts of rows that measured the rig
MEASURED = ("GO", "NO-GO")


def skip_row(registration: Registration, station: str, by: str, why_due: str) -> dict[str, Any]:
    """The history row of a due self-check the technician skipped: kept in the rig's ledger beside the checks, with
    no figures; it changes nothing of when the next check is due (:func:`last_check` reads measured rows only)."""
    from edc_bench import __version__

    return {"station": station, "reference_id": registration.id, "verdict": SKIPPED, "causes": "",
            "words": f"rig self-check skipped by {by or 'the operator'} (it was due: {why_due})",
            "simulated": registration.simulated, "details": json.dumps({"skipped": True, "due": why_due}),
            "software_version": __version__, "checked_by": by}


def _json_float(value: float) -> float | None:
    import math

    return value if math.isfinite(value) else None


def last_check(store: Any, registration: Registration) -> LastCheck:
    """The station's latest self-check against ``registration`` (a skip is none), or the registration itself (a
    check that passed) if none was made since; for :func:`selfcheck_due`."""
    checks = [row for row in store.rig_checks(registration.station, registration.id) if row.verdict in MEASURED]
    if checks:
        return LastCheck(dt.datetime.fromisoformat(checks[-1].checked_at), checks[-1].verdict == "GO")
    return LastCheck(dt.datetime.fromisoformat(registration.registered_at), True)


def check_due(store: Any, registration: Registration, policy: SelfCheckPolicy, now: dt.datetime) -> str | None:
    """Whether the station must run its self-check before its next test, and why (None: not due).

    Parameters
    ----------
    store : HistoryStore
        The station's history (open).
    registration : Registration
        The station's reference valve.
    policy : SelfCheckPolicy
        How often checks are required (``SelfCheckPolicy.of_variant(variant)``, or the strictest of several).
    now : datetime.datetime
        The time now, time-zone aware.

    Returns
    -------
    str or None
        :func:`selfcheck_due` on the station's latest check (or the registration) and the tests since it.
    """
    last = last_check(store, registration)
    tests = store.tests_since(registration.station, last.at.isoformat(timespec="seconds"))
    return selfcheck_due(last, tests, now, policy)


__all__ = ["MEASURED", "REGISTER_COMMAND", "SKIPPED", "Cause", "LastCheck", "Registration", "Rig", "SelfCheck", "SelfCheckPolicy",
           "SelfCheckResult", "check_due", "last_check", "measure_reference", "no_reference_line", "registration_row",
           "rig_check_row", "run_selfcheck", "selfcheck_due", "skip_row", "tolerances_of", "values_of"]
