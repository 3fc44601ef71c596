"""The figures of docs/faults.md: each fault provoked on the simulated rig, and the sentences the bench prints.

:func:`fault_reactions` (measurement ``faults-reactions``) injects every fault of the page's first table into a
test of a worn valve on ``p-edc-default`` in simulated time, as ``tests/runtime/test_faults.py`` does, and keeps
when the bench decided, when the rig's drive reached 0 V and by what, and the sentence the record holds.
:func:`bad_input_table` prints the variant loader's messages as it words them now (live).
"""

from __future__ import annotations

import itertools
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from figures.common import measurement, stored, table

#: Clock time of every injected fault (the rig boots in 0.2 s, the ticks start just after).
FAULT_AT_S = 2.5
#: Rig faults (``edc_bench.testing.faults.RIG_FAULTS``) and bus rules measured, by scenario name.
RIG_SCENARIOS = ("heartbeat_stops", "rig_fault", "over_current", "lvdt_disconnected", "lvdt_out_of_range",
                 "travel_limit", "current_nan", "lvdt_stuck")
BUS_SCENARIOS = ("drop-replies", "corrupt-replies", "stale-counter", "delayed-replies", "send-error", "bus-off",
                 "rig-cut-off")
#: The shipped variants the stuck-sensor row quotes the coil current for.
STUCK_SENSOR_VARIANTS = ("p-edc-default", "p-edc-long", "p-edc-hard")
_channels = itertools.count()


def _bus_rule(name: str) -> Any:
    """The :class:`~edc_bench.testing.faults.Rule` of bus scenario ``name`` (as tests/runtime/test_faults.py)."""
    from edc_bench.protocol import RIG_FEEDBACK_ID
    from edc_bench.testing.faults import Rule

    return {
        "drop-replies": Rule("drop", FAULT_AT_S, direction="rx", can_id=RIG_FEEDBACK_ID),
        "corrupt-replies": Rule("corrupt", FAULT_AT_S, can_id=RIG_FEEDBACK_ID),
        "stale-counter": Rule("repeat", FAULT_AT_S, FAULT_AT_S + 0.05, direction="tx"),
        "delayed-replies": Rule("delay", FAULT_AT_S, delay_s=0.005),
        "send-error": Rule("error", FAULT_AT_S, direction="tx"),
        "bus-off": Rule("bus_off", FAULT_AT_S),
        "rig-cut-off": Rule("cut", FAULT_AT_S),
    }[name]


class _DriveWatch:
    """The rig's hardware as its firmware sees it, every drive set logged with the rig's time."""

    def __init__(self, rig: Any) -> None:
        self._rig, self._hardware = rig, rig.hardware
        self.log: list[tuple[float, float]] = []

    def set_drive_v(self, drive_v: float) -> None:
        self.log.append((self._rig.time_s, drive_v))
        self._hardware.set_drive_v(drive_v)

    def __getattr__(self, name: str) -> Any:
        return getattr(self._hardware, name)


def _watch_drive(rig: Any) -> list[tuple[float, float]]:
    """Log every drive the rig's firmware sets, with the rig's time: [(time_s, drive_v), ...].

    The firmware is given a watching hardware (the rig's own object stays as it is).
    """
    watch = _DriveWatch(rig)
    rig.firmware.hw = watch
    return watch.log


def _first_safe_s(result: Any, after_s: float) -> float | None:
    """Clock time of the bench's first SAFE command at or after ``after_s`` (None: none was sent)."""
    from edc_bench.protocol import BENCH_CMD_ID, Mode, default_icd

    icd, frames = default_icd(), result.frames
    for k in range(frames.count):
        if (not frames.rx[k] and frames.can_id[k] == BENCH_CMD_ID and frames.t_s[k] >= after_s - 1e-9
                and icd.parse_bench_cmd(bytes(frames.data[k])).mode == Mode.SAFE):
            return float(frames.t_s[k])
    return None


def _sentence(abort: Any) -> str:
    """The record's reason; a bus error's python-can text (the fault injector's words here) left out."""
    from edc_bench.engine.abort_figures import ErrorFigures
    from edc_bench.engine.outcome import Abort, AbortKind, describe

    if abort.kind is AbortKind.BUS_ERROR:
        return describe(Abort(abort.kind, ErrorFigures(error=abort.figures.error.split(":")[0] + ": ...")))
    return abort.sentence


def _provoke(variant_name: str, rig_fault: str | None = None, rule: Any = None,
             prepare: Callable[[Any], None] | None = None) -> dict[str, Any]:
    """Run one test of a worn valve with a fault at :data:`FAULT_AT_S`; what the bench and the rig did."""
    import can
    import numpy as np

    from edc_bench.bench import BenchOptions, run_bench_test
    from edc_bench.config import load_variant
    from edc_bench.physics.valve import parse_valve_spec
    from edc_bench.runtime.clock import SimulatedClock
    from edc_bench.sim.inprocess import InProcessRig
    from edc_bench.sim.rig import SimulatedRig
    from edc_bench.testing.faults import FaultyBus, schedule_rig_fault

    variant = load_variant(variant_name)
    rig = SimulatedRig(variant, parse_valve_spec("worn", variant), 1)
    drives = _watch_drive(rig)
    if rig_fault:
        schedule_rig_fault(rig, rig_fault, FAULT_AT_S)
    if prepare:
        prepare(rig)
    channel = f"docs-faults-{next(_channels)}"
    bench_end = can.Bus(interface="virtual", channel=channel, preserve_timestamps=True)
    rig_end = can.Bus(interface="virtual", channel=channel, preserve_timestamps=True)
    clock = SimulatedClock(InProcessRig(rig_end, rig))
    bus = FaultyBus(bench_end, clock.now_s, [rule] if rule else [])
    try:
        result = run_bench_test(bus, clock, variant, BenchOptions(check_gains=False))
        clock.wait_until(clock.now_s() + 0.025)  # the rig's watchdog acts where the bus is gone
    finally:
        for end in (bus, bench_end, rig_end):
            end.shutdown()
    outcome = result.outcome
    detected_s = None if outcome.abort_time_s is None else outcome.ticks_start_s + outcome.abort_time_s
    safe_s = None if detected_s is None else _first_safe_s(result, detected_s)
    nonzero = [t for t, v in drives if v != 0.0]
    zero_s = next((t for t, v in drives if v == 0.0 and (not nonzero or t >= nonzero[-1])), None)
    trips = list(rig.firmware.counters.faults)  # the rig's own trips, in order (a later SAFE re-arms it)
    current_a = np.asarray(result.trace["current_a"])
    return {
        "exit_verdict": str(result.verdict),
        "kind": str(outcome.abort.kind) if outcome.abort else None,
        "sentence": _sentence(outcome.abort) if outcome.abort else None,
        "detected_after_ms": None if detected_s is None else round((detected_s - FAULT_AT_S) * 1e3, 1),
        "safe_after_detection_ms": None if safe_s is None else round((safe_s - detected_s) * 1e3, 1),
        "zero_v_after_fault_ms": None if zero_s is None else round((zero_s - FAULT_AT_S) * 1e3, 1),
        "zero_v_by": trips[0] if trips else "SAFE",
        "drive_v_end": float(rig.plant.drive_v),
        "max_current_a": round(float(np.nanmax(np.abs(current_a))), 2) if current_a.size else None,
        "over_current_a": variant.rig.over_current_a,
    }


def _never_ready(rig: Any) -> None:
    """A rig that never sends a heartbeat, so never reports READY."""
    rig.firmware.heartbeat_enabled = False


@measurement("faults-reactions", minutes=0.2)
def fault_reactions() -> dict[str, Any]:
    """Every measured fault on a worn valve of ``p-edc-default``, and the stuck sensor on each shipped variant."""
    runs: dict[str, Any] = {name: _provoke("p-edc-default", rig_fault=name) for name in RIG_SCENARIOS}
    runs.update({name: _provoke("p-edc-default", rule=_bus_rule(name)) for name in BUS_SCENARIOS})
    runs["never-ready"] = _provoke("p-edc-default", prepare=_never_ready)
    stuck = {name: _provoke(name, rig_fault="lvdt_stuck")["max_current_a"] for name in STUCK_SENSOR_VARIANTS}
    return {"fault_at_s": FAULT_AT_S, "runs": runs, "stuck_sensor_max_current_a": stuck}


# -- the table ------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Row:
    """One row of the fault table: what a person reads, and the scenario that measures it (if one does)."""

    fault: str
    detected_by: str
    reaction: str
    exit: str
    scenario: str | None = None
    safe: str = ""  # what brings the rig to 0 V, for a row no scenario measures
    says: str = ""  # the record's reason, for a row no scenario measures


def _ms(value: float) -> str:
    return f"{value:.0f} ms"


def _safe_cell(run: dict[str, Any]) -> str:
    """'detected X ms after the fault; 0 V Y ms after it, by ...' from a measured run."""
    parts = []
    if run["detected_after_ms"] is not None:
        parts.append(f"detected {_ms(run['detected_after_ms'])} after the fault")
    if run["safe_after_detection_ms"] is not None:
        parts.append(f"SAFE sent {_ms(run['safe_after_detection_ms'])} after detection")
    if run["zero_v_after_fault_ms"] is not None:
        by = {"SAFE": "by SAFE", "WATCHDOG": "by the rig's watchdog"}.get(run["zero_v_by"],
                                                                           f"by the rig's own trip ({run['zero_v_by']})")
        parts.append(f"rig at 0 V {_ms(run['zero_v_after_fault_ms'])} after the fault, {by}")
    return "; ".join(parts)


def _rows(variant: Any) -> list[Row]:
    """The rows of the fault table, in the page's order."""
    from edc_bench.engine.abort_figures import BusFloodedFigures, ErrorFigures, RigFaultFigures
    from edc_bench.engine.outcome import Abort, AbortKind, describe
    from edc_bench.engine.problems import Problem
    from edc_bench.records.advice import advice
    from edc_bench.verdict.pc_stall import RIG_ON_THIS_PC_REASON, pc_stall_reason
    from edc_bench.verdict.verdicts import Verdict

    a = variant.acceptance
    age = f"`max_reply_age_ms` ({a.max_reply_age_ms:g} ms)"
    return [
        Row("replies dropped", f"a command unanswered within {age} counts as missed; more than "
            f"{a.max_missed_replies_in_row} in a row with no reply at all", "abort, SAFE", "12", "drop-replies"),
        Row("replies corrupt (bad CRC)", "E2E check fails: counted as bad and missing", "as above", "12",
            "corrupt-replies"),
        Row("a few lost or corrupt replies", "counted; the newest sample is used while young enough, else the PID "
            "holds", "test goes on", "verdict", safe="n/a", says="`missed_replies` in timing; verdict as usual"),
        Row("stale counter (bench repeats a command)", "the rig ignores it, its reply is missing",
            f"abort after {a.max_missed_replies_in_row} in a row", "12", "stale-counter"),
        Row("replies late but within `max_reply_age_ms`", "matched by counter, used with their age "
            "(`sample_age_ticks`)", "test goes on", "verdict", safe="n/a", says="`loop.reply_age_ticks`"),
        Row("replies later than `max_reply_age_ms`, for good", "matched by counter, never used; their commands "
            "count as missed; the PID holds", "abort when no usable reply came for the rig's watchdog time", "12",
            "delayed-replies"),
        Row("replies held back a few ms once (a USB host controller, a busy rig)", "as above, but the replies keep "
            "coming", "the PID holds meanwhile; the test goes on", "verdict", safe="n/a",
            says="`missed_replies`, `loop.max_missed_in_row`, `replies_too_old`"),
        Row("frames reordered", "replies matched by counter whatever their order", "test goes on", "verdict",
            safe="n/a", says="verdict as usual"),
        Row(f"a bus that floods (more than `max_frames_per_tick`, {a.max_frames_per_tick}, frames in one tick)",
            "frame budget per tick", "abort, SAFE at the next tick; every read stays bounded", "12",
            safe="SAFE at the next tick", says="`" + describe(Abort(AbortKind.BUS_FLOODED, BusFloodedFigures(
                limit=a.max_frames_per_tick))) + "`"),
        Row("host stall shorter than the rig's watchdog", "a tick starts a period or more late", "the lost ticks are "
            "skipped (no burst), marked `gap` in the trace, counted; the test goes on", "verdict", safe="n/a",
            says="`loop.gaps`, `loop.ticks_lost`; the rows they touched are left out of the fit and what remains "
            "decides; INVALID for its timing only past `max_overrun_fraction` (with the ticks that ran late, "
            "`timing.ticks_late`) and without a trusted fit of what remains"),
        Row(f"host stall longer than the watchdog (`[rig].watchdog_ms`, {variant.rig.watchdog_ms:g} ms)",
            "the rig trips its watchdog", "abort, SAFE (re-arms)", "12", safe="rig at 0 V by its watchdog",
            says="`" + describe(Abort(AbortKind.RIG_FAULT, RigFaultFigures(flags=("watchdog tripped",)))) + "`, and `"
                 + pc_stall_reason(0.025, 0.0) + "`; the advice names the PC "
                 "(`" + advice(Verdict.INVALID, Problem.ABORTED | Problem.PC_STALLED).words + "`)"),
        Row("a rig that is a process on this PC (`test --realtime`'s rig process, or `edc-bench rig` on a loopback "
            "socket or a pseudo-terminal) stops answering: the PC did not run it in time", "replies missing, "
            "heartbeat lost or the rig's watchdog", "abort, SAFE", "12", safe="as the rig's own",
            says="the abort's sentence, and `" + RIG_ON_THIS_PC_REASON + "`; the advice names the PC, as for a stall "
                 "of the bench (`timing.rig_on_this_pc` in the record). `edc-bench rig` raises itself one above the "
                 "bench's real-time priority where the PC permits and says which it runs at (`rig: scheduling ...`)"),
        Row("python-can error on send or receive", "`CanOperationError`", "abort, SAFE attempted", "12", "send-error"),
        Row("bus-off", "every send and receive fails", "abort", "12", "bus-off"),
        Row("rig cut off", "replies missing", "abort", "12", "rig-cut-off"),
        Row("RIG_HEARTBEAT stops", f"no heartbeat for {a.heartbeat_timeout_periods:g} periods "
            f"({variant.rig.heartbeat_period_ms * a.heartbeat_timeout_periods:g} ms)", "abort, SAFE", "12",
            "heartbeat_stops"),
        Row("rig in FAULT (e.g. supply low)", "reply with amplifier off while running; heartbeat state",
            "abort, SAFE (re-arms)", "12", "rig_fault"),
        Row("over-current", "rig flag OverCurrent", "abort, SAFE", "12", "over_current"),
        Row("LVDT disconnected (NaN)", "rig flag LvdtFault", "abort, SAFE", "12", "lvdt_disconnected"),
        Row("LVDT out of range", "rig flag LvdtFault (bench also checks plausibility)", "abort, SAFE", "12",
            "lvdt_out_of_range"),
        Row("rack beyond its travel", "rig flag TravelLimit", "abort, SAFE", "12", "travel_limit"),
        Row("current sample NaN", "rig flag OverCurrent", "abort, SAFE", "12", "current_nan"),
        Row("sensor stuck in range, rack jammed", f"rack more than {a.max_tracking_error_mm:g} mm off its reference "
            f"for {a.tracking_error_ticks} ticks in a row (`acceptance.max_tracking_error_mm`, "
            "`tracking_error_ticks`)", "abort, SAFE", "12", "lvdt_stuck"),
        Row("rig never READY", f"no READY heartbeat within `acceptance.ready_timeout_s` ({a.ready_timeout_s:g} s)",
            "no command sent", "12", "never-ready", safe="rig never driven"),
        Row("Ctrl-C, SIGTERM", "stop request polled every tick and while waiting for READY",
            "abort, SAFE, the record written; further signals only noted", "130",
            safe="SAFE at the next tick", says="`" + describe(Abort(AbortKind.INTERRUPTED)) + "`"),
        Row("a bug in the bench (an exception in the tick)", "caught by the loop", "abort, SAFE; record with the "
            "traceback; exit 70", "70", safe="SAFE at the next tick",
            says="`" + describe(Abort(AbortKind.INTERNAL_ERROR, ErrorFigures(error="..."))) + "`"),
        Row("test process killed (SIGKILL)", "the rig's watchdog", "rig: 0 V, FAULT (WATCHDOG) until SAFE",
            "none (killed)", safe="rig at 0 V by its watchdog",
            says="no record.json; `can.log` readable up to the last 0.1 s"),
    ]


def _says(row: Row, run: dict[str, Any]) -> str:
    """The record-says cell of a measured row: the sentence, and for the stuck sensor its other wording."""
    text = f"`{run['sentence']}`"
    if row.scenario == "lvdt_stuck":
        text += ("; a rack that moved in those ticks, but not with its reference: `... (it moves, but the loop "
                 "cannot hold it: the variant's gains or model do not fit this pump, or the drive's polarity is "
                 "reversed)`")
    return text


def reaction_table() -> str:
    """The fault table: static columns from the code's settings, measured columns from ``faults-reactions``."""
    from edc_bench.config import load_variant

    runs = stored("faults-reactions")["runs"]
    rows = []
    for row in _rows(load_variant("p-edc-default")):
        if row.scenario:
            run = runs[row.scenario]
            rows.append((row.fault, row.detected_by, row.reaction, row.safe or _safe_cell(run), row.exit,
                         _says(row, run)))
        else:
            rows.append((row.fault, row.detected_by, row.reaction, row.safe, row.exit, row.says))
    header = ("fault", "detected by", "reaction", f"to safe state (measured, fault at {FAULT_AT_S:g} s)", "exit",
              "record says (reason)")
    return table(header, rows)


def stuck_sensor_sentence() -> str:
    """Why the stuck-sensor limit is 100 ticks: the coil current it lets the PID reach, on each shipped variant."""
    data = stored("faults-reactions")
    currents = data["stuck_sensor_max_current_a"].values()
    trip_a = data["runs"]["lvdt_stuck"]["over_current_a"]
    return (f"A stuck sensor is caught before the PID winds the coil up to the rig's over-current trip: the coil "
            f"reaches {min(currents):.1f}-{max(currents):.1f} A at the most (by variant) on the test variants "
            f"({', '.join(f'`{n}`' for n in data['stuck_sensor_max_current_a'])}) before the bench stops the test, "
            f"against the rig's trip at `[rig].over_current_a` ({trip_a:g} A on `p-edc-default`).")


# -- bad input ------------------------------------------------------------------------------------------------------

#: Rows of the bad-input table whose messages are not generated here: (input, example message, exit code).
OTHER_BAD_INPUT = (
    ('unstable or marginal PID gains',
     "`variant hot: PID gains ... make the loop unstable on the nominal plant ...; 'edc-bench tune --variant hot' proposes gains that keep the margins`",
     '2'),
    ('a variant without a measured baseline',
     "the test runs, then: `variant not calibrated: ... run 'edc-bench calibrate --variant V ... --append' once per valve ...`",
     '12 (INVALID)'),
    ('calibrate: no converged test',
     "each test's line `test 1/1: INVALID, not used: <reason>`, then `no converged new-valve test, so no baseline`",
     '12'),
    ('an output path that cannot be written (a file where a folder is meant, a device, a read-only folder)',
     '`--out records.txt: is a file, not a folder; give a folder (made if missing)`',
     '2'),
    ('a history URL that is no database, or whose folder is missing',
     '`history database sqlite:////nonexist/h.db: the folder /nonexist does not exist; make it first (mkdir -p /nonexist) or give another with --db URL` (nothing is created)',
     '2'),
    ('a valve id that is not text, has control characters or is too long',
     "`argument --valve-id: '...' is 101 characters long: at most 100`",
     '2'),
    ('an unknown `--interface`, `--channel` without `--interface`, a bad `CAN_INTERFACE`',
     'names the setting and the interfaces python-can knows',
     '2'),
    ('a bus that does not open',
     '`cannot open the CAN bus (interface=socketcan, channel=nosuchcan0): ...`',
     '3'),
    ("any of python-can's interfaces whose driver or package is missing, or that lacks a channel or an argument it "
     "requires (socketcand's host and port), by flag, environment or config file",
     "`cannot open the CAN bus (interface=kvaser, channel=0): NameError: ... (python-can: Kvaser canlib is "
     "unavailable.); kvaser needs Kvaser's CANlib driver ...`; `the socketcand interface needs --bus-option "
     "host=192.168.1.10 and --bus-option port=29536 ...`",
     '3'),
    ("python-can's config file that cannot be read (binary, no `[default]` line, a lone `%`), a `CAN_CONFIG` that "
     "is not a JSON object",
     "`/home/bench/.canrc: not a config file python-can can read: line 1, 'interface = kvaser', comes before any "
     "[section] line; ...` (a file in Latin-1, Windows-1252 or UTF-16 is read as such)",
     '3'),
    ('tune: no PID keeps the margins, or the variant file cannot be written',
     '`no PID gains keep 60 dB and 30 deg ...`; `cannot write the gains (...); copy the proposed gains ... by hand`',
     '2'),
    ('classify: missing or absurd values, missing record or model',
     '`give --af and --a1 ...`; values must be finite, positive and within 100 times the baseline; `not a readable record`; `classifier model ... not found`',
     '2'),
    ('baseline or dataset file damaged',
     '`...: baseline needs af_v and a1_v_s_per_mm as numbers`; `content does not match its recorded hash`',
     '2'),
)


def bad_input_table() -> str:
    """The bad-input table: the variant file's messages as ``load_variant`` prints them now (live), then the rest."""
    from figures.variants import MISTAKES, load_error, mistaken_default

    def said(old: str, new: str) -> str:
        return f"`{load_error(mistaken_default(old, new))}`"

    out_of_range, unknown_key, absurd = (said(old, new) for old, new in MISTAKES)
    missing = said("resistance_ohm = 0.7\n", "")
    not_toml = said("[pump]", "[pump\n")
    latin1_file = "description = 'Prüfstand'\n".encode("latin-1")
    latin1 = f"`{load_error(latin1_file)}`"
    # the TOML parser's own words (Python's tomllib) after the colon are left out: they are not edc-bench's
    not_toml = not_toml.split("TOML:")[0] + "TOML: ...`"
    rows = [
        ("variant value out of range", out_of_range, "2"),
        ("physically absurd value", absurd, "2"),
        ("unknown key", unknown_key, "2"),
        ("missing key, wrong type, inconsistent sections", (f"{missing}; travel limits, excitation swing, k < k_x, "
                                                            "over-current at full travel, drive limit, test too short"),
         "2"),
        ("not TOML, not UTF-8, missing file, unknown variant", (f"{not_toml}; {latin1}; `unknown variant 'nope': "
                                                                "give a name (...), a part number, or a path ...`"),
         "2"),
        *OTHER_BAD_INPUT,
    ]
    return table(("input", "example message", "exit"), rows)
