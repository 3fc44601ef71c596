"""``edc-bench rig-check``: does a rig keep ICD v1? A black-box conformance suite.

The checks (:mod:`~edc_bench.rigcheck.checks`) talk to the rig over the
bench's own bus and clock (:mod:`~edc_bench.rigcheck.session`), measure, and
name the rule each tests; :func:`run_rig_check` runs them in order and
leaves the rig in SAFE whatever happens. :mod:`~edc_bench.rigcheck.report`
writes the table, the JSON and the one-page PDF. GO when every check that
ran passed.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from edc_bench.canlib import can
from edc_bench.config.models import Variant
from edc_bench.protocol import Icd, Mode, default_icd
from edc_bench.rigcheck.checks import (
    CheckResult,
    Expectations,
    fault_flags,
    heartbeat,
    invalid_frames,
    replies_and_latency,
    safe_applies_zero,
    samples_before_drive,
    valid_command,
    watchdog,
)
from edc_bench.rigcheck.session import RigSession
from edc_bench.runtime.clock import Clock


@dataclass(frozen=True)
class RigCheckReport:
    """Every check's result, and what they add up to.

    Attributes
    ----------
    results : list of CheckResult
        In the order they ran.
    variant : str
        The variant whose rig section the rig was held to.
    where : str
        The bus, as given.
    expectations : dict
        The figures the rig was held to.
    when : str
        When the check ran (local date and time, for the filed report).
    worst_late_ms : float
        The latest this machine woke the checks after a wait: a figure of milliseconds means the bench side was
        not run on time, and timing checks may then blame the rig for the PC.
    frames_received : int
        Frames that came from the rig in all (none: nothing answers on this bus).
    """

    results: list[CheckResult]
    variant: str
    where: str
    expectations: dict[str, Any] = field(default_factory=dict)
    when: str = ""
    worst_late_ms: float = 0.0
    frames_received: int = 0

    @property
    def failed(self) -> list[CheckResult]:
        """The checks the rig failed."""
        return [r for r in self.results if r.passed is False]

    @property
    def go(self) -> bool:
        """GO: every check that ran passed."""
        return not self.failed


def run_rig_check(bus: can.BusABC, clock: Clock, variant: Variant, *, where: str = "", commands: int = 2000,
                  icd: Icd | None = None, on_result: Any = None, when: str = "",
                  provoke_trips: bool = False) -> RigCheckReport:
    """Run the conformance checks against the rig on ``bus``.

    Parameters
    ----------
    bus : can.BusABC
        The bench's end of the bus.
    clock : Clock
        Real time for a rig; the simulated clock stepping an in-process rig in tests.
    variant : Variant
        Whose rig section (watchdog, heartbeat, supply) and nominal plant (the hold drive) the rig is held to.
    where : str, optional
        The bus, for the report.
    commands : int, optional
        Commands in the reply-latency run.
    icd : Icd, optional
        The compiled ICD (the packaged one).
    on_result : callable, optional
        Called with each CheckResult as soon as it is known.
    when : str, optional
        When it runs, for the report.
    provoke_trips : bool, optional
        Also provoke the over-current and travel-limit trips (the rack to its stop, the coil beyond its rating
        for a millisecond): only on a rig built for it.

    Returns
    -------
    RigCheckReport
    """
    exp = Expectations.of(variant, commands)
    session = RigSession(bus, clock, icd or default_icd())
    results: list[CheckResult] = []

    def keep(found: list[CheckResult]) -> None:
        for result in found:
            results.append(result)
            if on_result is not None:
                on_result(result)

    try:
        keep(heartbeat(session, exp))
        keep(valid_command(session, exp))
        keep(invalid_frames(session, exp))
        latency = replies_and_latency(session, exp)
        keep(latency)
        p99_ms = latency[-1].figures.get("p99_ms")
        slack_ms = 2.0 + (p99_ms if p99_ms == p99_ms and p99_ms is not None else 0.0)  # NaN: no replies
        keep(watchdog(session, exp, slack_ms))
        keep(safe_applies_zero(session, exp))
        keep(samples_before_drive(session, exp))
        keep(fault_flags(session, exp, provoke_trips))
    finally:
        try:  # whatever happened: the amplifier off
            session.command(Mode.SAFE)
            session.wait(0.005)
        except (can.CanError, OSError):  # the bus itself failed: what failed it is the error to report
            pass
    return RigCheckReport(results, variant.name, where, {
        "watchdog_ms": exp.watchdog_ms, "heartbeat_period_ms": exp.heartbeat_period_ms,
        "supply_min_v": exp.supply_min_v, "max_reply_age_ms": exp.max_reply_age_ms,
        "hold_drive_v": round(exp.hold_drive_v, 4), "hold_current_a": round(exp.hold_current_a, 4),
        "commands": exp.commands}, when, session.worst_late_s * 1e3, len(session.received))


__all__ = ["CheckResult", "RigCheckReport", "run_rig_check"]
