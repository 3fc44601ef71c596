"""The figures of docs/rig-check.md, live: the hold drive from the variant, and the simulated rigs checked.

The simulated checks run in simulated time (a fraction of a second each), so the page says what the checks
find on the simulated rig and on each broken one as the code is now.
"""

from __future__ import annotations

from typing import Any

from figures.common import table


def _check(breaks: frozenset[Any] = frozenset(), commands: int = 2000, provoke_trips: bool = False) -> Any:
    from edc_bench.config import load_variant
    from edc_bench.physics.valve import parse_valve_spec
    from edc_bench.rigcheck import run_rig_check
    from edc_bench.runtime.bus import ClosingBus
    from edc_bench.runtime.clock import SimulatedClock
    from edc_bench.sim.inprocess import InProcessRig
    from edc_bench.sim.lockstep_bus import lockstep_pair
    from edc_bench.sim.rig import RigOptions, SimulatedRig

    variant = load_variant()
    rig = SimulatedRig(variant, parse_valve_spec("new", variant), options=RigOptions(breaks=breaks))
    bench_end, rig_end = lockstep_pair()
    with ClosingBus(bench_end) as bus, ClosingBus(rig_end):
        return run_rig_check(bus, SimulatedClock(InProcessRig(rig_end, rig)), variant, commands=commands,
                             provoke_trips=provoke_trips)


def hold_drive_sentence() -> str:
    """The hold drive on the default variant."""
    from edc_bench.config import load_variant
    from edc_bench.rigcheck.checks import Expectations

    exp = Expectations.of(load_variant())
    return (f"On `p-edc-default` that is {exp.hold_drive_v:.2f} V, for {exp.hold_current_a:.2f} A in its "
            "nominal coil.")


def simulated_table() -> str:
    """Every check on the simulated rig (simulated time, no adapter, the trips provoked): what a GO looks like."""
    report = _check(provoke_trips=True)
    from edc_bench.rigcheck.report import mark

    rows = [(r.title, mark(r), r.measured) for r in report.results]
    verdict = "GO" if report.go else "NO-GO"
    return table(("check", "result", "measured"), rows) + f"\n\n`edc-bench rig-check` on the simulated rig: {verdict}."


def breaks_table() -> str:
    """Each broken rig, and the checks that fail on it (simulated time)."""
    from edc_bench.sim.broken_rigs import IcdBreak

    rows = []
    for rule in IcdBreak:
        report = _check(frozenset({rule}), commands=400)
        failed = "; ".join(f"{r.title}: {r.measured}" for r in report.failed) or "none"
        not_checked = ", ".join(r.title for r in report.results if r.passed is None and r.key != "trip_flags")
        rows.append((f"`{rule.value}`", "GO" if report.go else "NO-GO", failed, not_checked or "-"))
    return table(("`--break`", "verdict", "the checks that fail, as measured", "not checked as a result"), rows)
