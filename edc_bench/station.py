"""Can this PC hold the bench loop's rate? A cyclictest for the bench loop, with advice.

The check runs the loop's own clock for a few seconds with nothing else in
the tick (:func:`edc_bench.perf.loops.bare_loop`), beside a sampler of the
hypervisor's steal, and reads what the system says about itself (CPU
governor, load, busy programs, real-time priority, power supply). The
verdict is GO when the loop's lateness leaves the tick's work room to run
and overruns stay under the variant's limit.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from edc_bench.runtime.priority import how_to_allow, realtime_now, realtime_permitted, realtime_priority

#: GO needs the p99.9 lateness under this share of the period (the rest is the tick's work and the reply).
LATENESS_SHARE = 0.3


@dataclass
class StationCheck:
    """What the check measured and what it advises."""

    period_s: float
    duration_s: float
    ticks: int
    lateness_us: dict[str, float]
    overruns: int
    overrun_limit: float
    steal_s: float
    verdict: str
    reasons: list[str] = field(default_factory=list)
    advice: list[str] = field(default_factory=list)
    system: dict[str, object] = field(default_factory=dict)


def _read(path: str) -> str | None:
    try:
        return Path(path).read_text(encoding="ascii", errors="replace").strip()
    except OSError:
        return None


def _busy_programs(min_share: float = 0.1, sample_s: float = 0.5) -> list[tuple[str, float, int]]:
    """Other processes using at least ``min_share`` of a CPU, measured over ``sample_s``: (name, share, pid), the
    busiest first (the pid tells apart two of one name, and is what ``kill`` or the task manager takes)."""
    import time

    def times() -> dict[int, tuple[str, int]]:
        out = {}
        for entry in Path("/proc").iterdir():
            if not entry.name.isdigit() or int(entry.name) == os.getpid():
                continue
            stat = _read(f"/proc/{entry.name}/stat")
            if not stat or ")" not in stat:
                continue
            name = stat[stat.index("(") + 1: stat.rindex(")")]
            fields = stat[stat.rindex(")") + 2:].split()
            out[int(entry.name)] = (name, int(fields[11]) + int(fields[12]))
        return out

    before = times()
    time.sleep(sample_s)
    after = times()
    hz = os.sysconf("SC_CLK_TCK")
    busy = []
    for pid, (name, ticks) in after.items():
        if pid in before:
            share = (ticks - before[pid][1]) / hz / sample_s
            if share >= min_share:
                busy.append((name, share, pid))
    return sorted(busy, key=lambda item: -item[1])


def system_facts() -> dict[str, object]:
    """Governor, load, real-time priority permission, power supply (where the OS tells)."""
    facts: dict[str, object] = {"cpus": os.cpu_count()}
    facts["governor"] = _read("/sys/devices/system/cpu/cpu0/cpufreq/scaling_governor")
    load = _read("/proc/loadavg")
    facts["load_1min"] = float(load.split()[0]) if load else None
    facts["realtime_priority_allowed"] = realtime_permitted()
    facts["realtime_scheduling_now"] = realtime_now()
    online = [_read(str(p / "online")) for p in Path("/sys/class/power_supply").glob("A*")] \
        if Path("/sys/class/power_supply").exists() else []
    facts["on_battery"] = bool(online) and all(v == "0" for v in online)
    return facts


def judge(period_s: float, late_s: np.ndarray, steal_s: float, overrun_limit: float,
          facts: dict[str, object], busy: list[tuple[str, float, int]]) -> tuple[str, list[str], list[str]]:
    """GO or NO-GO, why, and what to do about it."""
    p999 = float(np.percentile(late_s, 99.9)) if len(late_s) else float("inf")
    overruns = int((late_s > period_s).sum())
    share = overruns / max(len(late_s), 1)
    reasons, advice = [], []
    if p999 > LATENESS_SHARE * period_s:
        reasons.append(f"p99.9 lateness {p999 * 1e6:.0f} us is more than {LATENESS_SHARE:.0%} of the "
                       f"{period_s * 1e3:g} ms tick")
    if share > overrun_limit:
        reasons.append(f"{overruns} of {len(late_s)} ticks overran ({share:.2%}; a test allows {overrun_limit:.1%})")
    if steal_s > 0.01:
        advice.append(f"The hypervisor took {steal_s:.2f} s of CPU during the check: this PC is a virtual machine "
                      "sharing its cores. A bench station needs a physical PC or dedicated (pinned) cores.")
    if busy:
        names = ", ".join(f"{name} (pid {pid}, {share:.0%} of a CPU)" for name, share, pid in busy[:5])
        advice.append(f"Close the programs using CPU: {names}.")
    if facts.get("governor") not in (None, "performance"):
        advice.append(f"The CPU governor is '{facts['governor']}': set it to 'performance' "
                      "(sudo cpupower frequency-set -g performance) so the clock does not slow down between ticks.")
    if facts.get("on_battery"):
        advice.append("The PC runs on battery: plug it in (power saving throttles the CPU).")
    if not facts.get("realtime_scheduling_now") and not facts.get("realtime_priority_allowed"):
        # permitted, the bench raises its own priority for each test (runtime/priority.py): nothing to do
        advice.append("The bench cannot raise its own priority for its tests: " + how_to_allow() + ".")
    return ("NO-GO" if reasons else "GO"), reasons, advice


def check_station(period_s: float, duration_s: float, overrun_limit: float) -> StationCheck:
    """Measure for ``duration_s`` at ``period_s`` and judge."""
    from edc_bench.perf.loops import bare_loop
    from edc_bench.runtime.clock import cpu_steal_s

    busy = _busy_programs()
    steal0 = cpu_steal_s()
    with realtime_priority() as priority:  # at the priority a test runs at
        late, _ = bare_loop(period_s, duration_s)
    steal = cpu_steal_s() - steal0
    # what the raise did, not what the limits predict (a cgroup without a real-time budget refuses it too)
    facts = {**system_facts(), "measured_at": priority.describe(), "realtime_priority_allowed": priority.realtime}
    verdict, reasons, advice = judge(period_s, late, steal, overrun_limit, facts, busy)
    q = np.percentile(late, [50, 99, 99.9]) * 1e6
    return StationCheck(
        period_s=period_s, duration_s=duration_s, ticks=len(late),
        lateness_us={"p50": float(q[0]), "p99": float(q[1]), "p99.9": float(q[2]), "max": float(late.max() * 1e6)},
        overruns=int((late > period_s).sum()), overrun_limit=overrun_limit, steal_s=steal, verdict=verdict,
        reasons=reasons, advice=advice, system={**facts, "busy_programs": busy},
    )
