"""The ICD v1 conformance checks, each measured, each naming the rule it tests.

Each check takes a :class:`~edc_bench.rigcheck.session.RigSession` and the
rig's :class:`Expectations`, talks to the rig, and gives a
:class:`CheckResult`. Every check starts by bringing the rig to READY with a
SAFE command and leaves it there. The only drive a check applies is
:attr:`Expectations.hold_drive_v`, whose force is half the spring's preload:
the rack stays on its stop.

Replies are matched to commands by order, not by their counter, so a rig
that echoes the wrong counter fails the echo check alone.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from edc_bench.config.models import Variant
from edc_bench.physics.valve import nominal_plant
from edc_bench.protocol import FaultCode, Mode, RigState
from edc_bench.rigcheck.session import RigSession, Sent

#: How long a check waits for a reply that should (or must not) come.
REPLY_WINDOW_S = 0.020
TICK_S = 0.001


@dataclass(frozen=True)
class Expectations:
    """What the ICD and the variant's rig section ask of this rig.

    Attributes
    ----------
    watchdog_ms, heartbeat_period_ms : float
        The rig's watchdog time and heartbeat period.
    supply_min_v, supply_nominal_v : float
        The amplifier supply's minimum and nominal voltage.
    max_reply_age_ms : float
        The oldest reply the bench uses (``acceptance.max_reply_age_ms``).
    hold_drive_v : float
        The drive the checks apply: its steady force is half the spring's preload, so the rack does not move.
    hold_current_a : float
        The coil current it gives (the variant's nominal coil).
    commands : int
        Commands in the reply-latency run (at 1 kHz).
    drive_limit_v, over_current_a, travel_max_mm : float
        The rig section's limits (the provoked trips).
    travel_drive_v : float
        A drive whose steady force takes the rack past ``travel_max_mm`` with a fifth to spare (the provoked
        travel trip).
    """

    watchdog_ms: float
    heartbeat_period_ms: float
    supply_min_v: float
    supply_nominal_v: float
    max_reply_age_ms: float
    hold_drive_v: float
    hold_current_a: float
    commands: int = 2000
    drive_limit_v: float = 24.0
    over_current_a: float = 15.0
    travel_max_mm: float = 19.5
    travel_drive_v: float = 0.0

    @classmethod
    def of(cls, variant: Variant, commands: int = 2000) -> Expectations:
        """From ``variant``'s rig section, acceptance and nominal plant."""
        plant, rig = nominal_plant(variant), variant.rig
        hold_current_a = 0.5 * plant.preload_n / plant.force_constant_n_per_a
        volts_per_amp = plant.resistance_ohm / plant.amplifier_gain
        travel_a = 1.2 * (plant.preload_n + plant.net_stiffness_n_per_mm * rig.travel_max_mm) / \
            plant.force_constant_n_per_a
        return cls(rig.watchdog_ms, rig.heartbeat_period_ms, rig.supply_min_v, rig.supply_voltage_v,
                   variant.acceptance.max_reply_age_ms, hold_current_a * volts_per_amp, hold_current_a, commands,
                   rig.drive_limit_v, rig.over_current_a, rig.travel_max_mm,
                   min(travel_a * volts_per_amp, rig.drive_limit_v))


@dataclass(frozen=True)
class CheckResult:
    """One check: the rule, what was measured, and whether the rig keeps the rule.

    Attributes
    ----------
    key : str
        Short name (JSON, tests).
    title : str
        What is checked, in a few words.
    rule : str
        The ICD rule, with where firmware_proto/PROTOCOL.md states it.
    measured : str
        The figure, for people.
    passed : bool or None
        None: not checked (``measured`` says why).
    figures : dict
        The numbers behind ``measured``.
    """

    key: str
    title: str
    rule: str
    measured: str
    passed: bool | None
    figures: dict[str, Any] = field(default_factory=dict)


def to_ready(session: RigSession) -> list[Any]:
    """A SAFE command (which also clears a latched fault), and the replies within the reply window."""
    sent = session.command(Mode.SAFE)
    session.wait(REPLY_WINDOW_S)
    return [fb for _, fb in session.feedback(sent.t_s)]


def run_at_1khz(session: RigSession, mode: Mode | int, drive_v: float, count: int) -> list[Sent]:
    """``count`` commands a millisecond apart (the last followed by a millisecond)."""
    sent = []
    start = session.now_s()
    for k in range(count):
        session.wait_until(start + k * TICK_S)
        sent.append(session.command(mode, drive_v))
    session.wait_until(start + count * TICK_S)
    return sent


# -- heartbeat -------------------------------------------------------------------------------------------------------

def heartbeat(session: RigSession, exp: Expectations) -> list[CheckResult]:
    """Listen for a second (and a period): the heartbeat's period and jitter, the firmware version, the supply."""
    period_s = exp.heartbeat_period_ms * 1e-3
    start = session.now_s()
    session.wait(1.0 + period_s)
    beats = [(t, hb) for t, hb in session.heartbeats(start) if hb is not None]
    rule = f"RIG_HEARTBEAT every {exp.heartbeat_period_ms:g} ms on a fixed grid (PROTOCOL.md, Timing)"
    if len(beats) < 2:
        return [CheckResult("heartbeat", "heartbeat period", rule, f"{len(beats)} heartbeats in "
                            f"{1.0 + period_s:g} s", False, {"beats": len(beats)}),
                CheckResult("supply", "supply voltage", "heartbeat SupplyVoltage at or above the minimum",
                            "not checked: no heartbeat", None)]
    times = [beats[0][0]]
    for t, _ in beats[1:]:  # a state change announced on a grid beat's time: one beat
        if t - times[-1] > 0.2 * period_s:
            times.append(t)
    gaps_ms = np.diff(times) * 1e3 if len(times) > 1 else np.array([math.inf])
    median_ms, jitter_ms = float(np.median(gaps_ms)), float(np.max(np.abs(gaps_ms - exp.heartbeat_period_ms)))
    # a beat announcing a state change comes between grid beats: the median is the grid's period
    ok = abs(median_ms - exp.heartbeat_period_ms) <= 0.1 * exp.heartbeat_period_ms
    last = beats[-1][1]
    supply_v = float(last.supply_v)
    supply_ok = exp.supply_min_v <= supply_v <= 2.0 * exp.supply_nominal_v
    states = sorted({hb.state.name for _, hb in beats})
    return [
        CheckResult("heartbeat", "heartbeat period", rule,
                    f"{median_ms:.1f} ms median, {jitter_ms:.1f} ms jitter (max), {len(beats)} beats; states "
                    f"{', '.join(states)}; firmware {last.fw_major}.{last.fw_minor}", ok,
                    {"median_ms": median_ms, "jitter_ms": jitter_ms, "beats": len(beats), "states": states,
                     "firmware": f"{last.fw_major}.{last.fw_minor}"}),
        CheckResult("supply", "supply voltage",
                    f"SupplyVoltage {exp.supply_min_v:g} V or more (the rig trips SUPPLY_LOW below), and plausible "
                    f"(at most twice the nominal {exp.supply_nominal_v:g} V)", f"{supply_v:.2f} V", supply_ok,
                    {"supply_v": supply_v}),
    ]


# -- a valid command, and frames that are not one --------------------------------------------------------------------

def valid_command(session: RigSession, exp: Expectations) -> list[CheckResult]:
    """A SAFE command: answered once, echoing its counter; the rig in READY afterwards."""
    to_ready(session)
    sent = session.command(Mode.SAFE)
    session.wait(REPLY_WINDOW_S + exp.heartbeat_period_ms * 1e-3)
    replies = session.feedback(sent.t_s, sent.t_s + REPLY_WINDOW_S)
    good = [fb for _, fb in replies if fb is not None]
    states = [hb.state for _, hb in session.heartbeats(sent.t_s) if hb is not None]
    ok = len(replies) == 1 and len(good) == 1 and not good[0].amp_enabled and states[-1:] in ([], [RigState.READY])
    measured = (f"{_count(len(replies), 'reply', 'replies')} ({len(replies) - len(good)} with a bad CRC or "
                f"length); amplifier "
                f"{'on' if good and good[0].amp_enabled else 'off'}; state after: "
                f"{states[-1].name if states else 'no heartbeat'}")
    return [CheckResult("answered", "valid command answered once",
                        "a valid BENCH_CMD gets one RIG_FEEDBACK with a correct CRC; SAFE leaves the amplifier off "
                        "in READY (PROTOCOL.md, Handling a valid command)", measured, ok,
                        {"replies": len(replies), "bad_replies": len(replies) - len(good)})]


def invalid_frames(session: RigSession, exp: Expectations) -> list[CheckResult]:
    """Frames that are not commands: a bad CRC, a wrong length, an undefined Mode, a repeated counter."""
    rule = "an invalid frame is ignored: no reply, no drive, its counter not taken (PROTOCOL.md, E2E protection)"
    out = []
    cases = [("bad_crc", "bad CRC ignored", {"mode": Mode.RUN, "drive_v": exp.hold_drive_v, "bad_crc": True}),
             ("wrong_length", "wrong DLC ignored", {"mode": Mode.RUN, "drive_v": exp.hold_drive_v, "length": 7}),
             ("undefined_mode", "undefined Mode ignored", {"mode": 2, "drive_v": exp.hold_drive_v})]
    for key, title, frame in cases:
        to_ready(session)
        sent = session.command(frame.pop("mode"), **frame)
        session.wait(REPLY_WINDOW_S)
        replies = len(session.feedback(sent.t_s))
        states = [hb.state.name for _, hb in session.heartbeats(sent.t_s) if hb is not None]
        driving = [s for s in states if s != RigState.READY.name]
        out.append(CheckResult(key, title, rule, f"{_count(replies, 'reply', 'replies')}; state changes: {', '.join(driving) or 'none'}",
                               replies == 0 and not driving, {"replies": replies, "states": states}))
    to_ready(session)
    first = session.command(Mode.SAFE)
    session.wait(REPLY_WINDOW_S)
    again = session.command(Mode.SAFE, counter=first.counter)
    session.wait(REPLY_WINDOW_S)
    replies = len(session.feedback(again.t_s))
    out.append(CheckResult("repeated_counter", "repeated counter ignored",
                           "a command whose counter equals the last accepted one is ignored (PROTOCOL.md, E2E "
                           "protection)", f"{_count(replies, 'reply', 'replies')} to the repeat", replies == 0, {"replies": replies}))
    return out


# -- every command answered, in order, with its counter; how fast -----------------------------------------------------

def replies_and_latency(session: RigSession, exp: Expectations) -> list[CheckResult]:
    """``exp.commands`` RUN commands at 0 V, at 1 kHz: each answered once, in order, echoing its counter; the reply
    latency's p50, p99 and maximum."""
    to_ready(session)
    sent = run_at_1khz(session, Mode.RUN, 0.0, exp.commands)
    session.wait(REPLY_WINDOW_S)
    replies = session.feedback(sent[0].t_s)
    to_ready(session)
    good = [(t, fb) for t, fb in replies if fb is not None]
    paired = min(len(good), len(sent))
    latency_ms = np.array([(good[j][0] - sent[j].t_s) * 1e3 for j in range(paired)])
    echoed = sum(good[j][1].counter == sent[j].counter for j in range(paired))
    p50, p99, worst = (np.percentile(latency_ms, [50, 99]).tolist() + [float(latency_ms.max())]) if paired else \
        [math.nan] * 3
    return [
        CheckResult("every_command", "every command answered",
                    "one RIG_FEEDBACK per valid command, every one (PROTOCOL.md, Timing)",
                    f"{len(replies)} replies to {len(sent)} commands ({len(replies) - len(good)} with a bad CRC)",
                    len(replies) == len(sent) == len(good), {"commands": len(sent), "replies": len(replies)}),
        CheckResult("counter_echo", "counter echoed",
                    "RIG_FEEDBACK.Counter is the command's counter (PROTOCOL.md, Frames)",
                    f"{echoed} of {paired} replies echo their command's counter", paired > 0 and echoed == paired,
                    {"echoed": echoed, "paired": paired}),
        CheckResult("reply_latency", "reply latency",
                    f"answered at once; the bench uses replies up to {exp.max_reply_age_ms:g} ms old "
                    "(PROTOCOL.md, Timing; acceptance.max_reply_age_ms)",
                    f"p50 {p50:.2f} ms, p99 {p99:.2f} ms, max {worst:.2f} ms over {paired} commands",
                    paired > 0 and p99 <= exp.max_reply_age_ms,
                    {"p50_ms": p50, "p99_ms": p99, "max_ms": worst}),
    ]


# -- the watchdog -----------------------------------------------------------------------------------------------------

def watchdog(session: RigSession, exp: Expectations, slack_ms: float) -> list[CheckResult]:
    """A gap in the commands a little shorter than the watchdog must not trip it, one ``slack_ms`` longer must;
    after a trip the drive is off, RUN is answered but not applied, and only SAFE re-arms the rig."""
    wd_s, slack_s = exp.watchdog_ms * 1e-3, slack_ms * 1e-3
    tripped = {}
    for label, gap_s in (("short", 0.75 * wd_s), ("long", wd_s + slack_s)):
        to_ready(session)
        run_at_1khz(session, Mode.RUN, exp.hold_drive_v, 20)
        session.wait(gap_s - TICK_S)
        probe = session.command(Mode.RUN, exp.hold_drive_v)
        session.wait(REPLY_WINDOW_S)
        replies = [fb for _, fb in session.feedback(probe.t_s) if fb is not None]
        tripped[label] = bool(replies and replies[0].watchdog_tripped)
        tripped[f"{label}_gap_ms"] = gap_s * 1e3
    # how long it took, from the heartbeat announcing the trip (where the rig sends one)
    to_ready(session)
    last = run_at_1khz(session, Mode.RUN, exp.hold_drive_v, 20)[-1]
    session.wait(10 * wd_s)
    trips = [t for t, hb in session.heartbeats(last.t_s)
             if hb is not None and hb.state is RigState.FAULT and hb.fault_code is FaultCode.WATCHDOG]
    trip_ms = (trips[0] - last.t_s) * 1e3 if trips else math.nan
    timing = f"; heartbeat announced the trip {trip_ms:.1f} ms after the last command" if trips else \
        "; no heartbeat announced a trip"
    watchdog_result = CheckResult(
        "watchdog", "watchdog trips in time",
        f"no valid command for {exp.watchdog_ms:g} ms in RUNNING: 0 V, WatchdogTripped, FAULT (PROTOCOL.md, Watchdog)",
        f"a {tripped['short_gap_ms']:.0f} ms gap {'tripped it' if tripped['short'] else 'did not'}, a "
        f"{tripped['long_gap_ms']:.0f} ms gap {'did' if tripped['long'] else 'did not trip it'}{timing}",
        tripped["long"] and not tripped["short"], {**tripped, "trip_ms": trip_ms})
    # tripped: RUN answered, not applied (the coil's current gone); SAFE re-arms; RUN then applies again
    after = session.command(Mode.RUN, exp.hold_drive_v)
    session.wait(REPLY_WINDOW_S)
    in_fault = [fb for _, fb in session.feedback(after.t_s) if fb is not None]
    rearmed = to_ready(session)
    again = session.command(Mode.RUN, exp.hold_drive_v)
    session.wait(REPLY_WINDOW_S)
    running = [fb for _, fb in session.feedback(again.t_s) if fb is not None]
    to_ready(session)
    if not in_fault or not in_fault[0].watchdog_tripped:  # nothing latched to check
        return [watchdog_result, CheckResult(
            "watchdog_latch", "tripped until SAFE", _LATCH_RULE,
            f"not checked: the watchdog did not trip within {10 * exp.watchdog_ms:g} ms", None)]
    held = in_fault[0].watchdog_tripped and not in_fault[0].amp_enabled
    off = bool(in_fault) and abs(in_fault[0].current_a) < 0.1 * exp.hold_current_a
    cleared = bool(rearmed) and rearmed[0] is not None and not rearmed[0].watchdog_tripped
    resumed = bool(running) and running[0].amp_enabled
    latch = (f"RUN after the trip: {'answered, not applied' if held else 'applied'}, coil current "
             f"{in_fault[0].current_a:.3f} A" if in_fault else "RUN after the trip: no reply")
    latch += f"; SAFE {'cleared' if cleared else 'did not clear'} it; RUN then {'applied' if resumed else 'not applied'}"
    return [
        watchdog_result,
        CheckResult("watchdog_latch", "tripped until SAFE", _LATCH_RULE, latch, held and off and cleared and resumed,
                    {"held": held, "drive_off": off, "cleared": cleared, "resumed": resumed}),
    ]


# -- SAFE, and when the samples are taken -------------------------------------------------------------------------------

def safe_applies_zero(session: RigSession, exp: Expectations) -> list[CheckResult]:
    """Hold the drive 20 ms, then SAFE: the coil's current must fall to (nearly) nothing within 10 ms."""
    replies = _in_order(session, [(Mode.RUN, 0.0, REST), (Mode.RUN, exp.hold_drive_v, 20), (Mode.SAFE, 0.0, 12)])
    if replies is None:
        return [CheckResult("safe", "SAFE applies 0 V", _SAFE_RULE, "replies missing: no current to compare", False)]
    rest, held, safe = replies
    held_a = held[-1].current_a - rest
    left_a = safe[10].current_a - rest  # sampled 10 ms after SAFE took effect
    ratio = left_a / held_a if abs(held_a) > 1e-9 else math.nan
    ok = abs(held_a) > 0.2 * exp.hold_current_a and abs(ratio) < 0.1 and not safe[0].amp_enabled
    return [CheckResult("safe", "SAFE applies 0 V", _SAFE_RULE,
                        f"coil current {held_a:.3f} A above rest while held, {left_a:.3f} A 10 ms after SAFE "
                        f"({ratio * 100:.0f} %); amplifier {'on' if safe[0].amp_enabled else 'off'} after SAFE", ok,
                        {"held_a": held_a, "left_a": left_a, "ratio": ratio})]


_LATCH_RULE = ("after a trip the drive stays at 0 V and RUN is answered but not applied; only SAFE re-arms "
               "(PROTOCOL.md, Watchdog; States)")
_SAFE_RULE = "SAFE sets 0 V at once and the amplifier off (PROTOCOL.md, Handling a valid command; States)"
REST = 10  # commands at 0 V before a step: any current left from before has gone


def _in_order(session: RigSession, phases: list[tuple[Mode, float, int]]) -> tuple[Any, ...] | None:
    """From READY, run each phase's commands at 1 kHz, back to back; the replies of each phase (by order: a reply
    comes a few ms late through an adapter), the first phase as its last three's mean current. None if replies are
    missing (the every-command check names that)."""
    to_ready(session)
    first = None
    for mode, drive_v, count in phases:
        sent = run_at_1khz(session, mode, drive_v, count)
        first = first if first is not None else sent[0]
    session.wait(REPLY_WINDOW_S)
    replies = [fb for _, fb in session.feedback(first.t_s) if fb is not None]
    to_ready(session)
    if len(replies) < sum(count for _, _, count in phases):
        return None
    out: list[Any] = []
    at = 0
    for _, _, count in phases:
        out.append(replies[at:at + count])
        at += count
    out[0] = _mean_current(out[0][-3:])
    return tuple(out)


def samples_before_drive(session: RigSession, exp: Expectations, repeats: int = 3) -> list[CheckResult]:
    """A step of the hold drive from rest: the reply to the step's first command must carry the current from before
    it (no rise yet), where later replies show the coil's current rising."""
    ratios = []
    for _ in range(repeats):
        replies = _in_order(session, [(Mode.RUN, 0.0, REST), (Mode.RUN, exp.hold_drive_v, 6)])
        if replies is None:
            continue
        rest, step = replies
        per_ms = (step[4].current_a - rest) / 4.0
        if abs(per_ms) > 1e-9:
            ratios.append((step[0].current_a - rest) / per_ms)
    rule = ("RIG_FEEDBACK carries the samples taken before the command's drive was applied (PROTOCOL.md, Handling "
            "a valid command, steps 1 and 4)")
    if not ratios:
        return [CheckResult("samples_first", "samples before the drive", rule, "replies missing: nothing to measure",
                            False)]
    ratio = float(np.median(ratios))
    return [CheckResult("samples_first", "samples before the drive", rule,
                        f"the step's first reply shows {ratio * 100:.0f} % of a millisecond's rise of the coil "
                        f"current (median of {len(ratios)} steps; 0 % when sampled first)", abs(ratio) < 0.25,
                        {"rise_ratio": ratio, "steps": len(ratios)})]


def _count(n: int, one: str, many: str) -> str:
    return f"{n} {one if n == 1 else many}"


def _mean_current(replies: list[Any]) -> float:
    currents = [fb.current_a for fb in replies if fb is not None]
    return float(np.mean(currents)) if currents else 0.0


def fault_flags(session: RigSession, exp: Expectations, provoke: bool = False) -> list[CheckResult]:
    """The travel-limit and over-current trips. Provoked only when asked (``provoke``): on a real rig that drives
    the rack to its stop and the coil beyond its rating for a millisecond. Otherwise listed as not checked, so that
    a report says what was not."""
    rule = ("a sample beyond the travel or the current limit trips FAULT with its flag and its fault code, the "
            "drive at 0 V (PROTOCOL.md, Trips and fault codes)")
    if not provoke:
        return [CheckResult("trip_flags", "travel-limit and over-current trips", rule,
                            "not checked: provoking them drives the rack to its stop or the coil beyond its rating "
                            "(--provoke-trips on a rig built for it)", None)]
    return [_provoked(session, "over_current", "over-current trip", rule, exp.drive_limit_v, 10, "over_current",
                      FaultCode.OVER_CURRENT),
            _provoked(session, "travel_limit", "travel-limit trip", rule, exp.travel_drive_v, 400, "travel_limit",
                      FaultCode.TRAVEL_LIMIT)]


def _provoked(session: RigSession, key: str, title: str, rule: str, drive_v: float, ticks: int, flag: str,
              code: FaultCode) -> CheckResult:
    """RUN at ``drive_v`` for up to ``ticks`` ms: the rig must trip with ``flag`` and ``code``, its drive off."""
    to_ready(session)
    start = session.now_s()
    sent = run_at_1khz(session, Mode.RUN, drive_v, ticks)
    session.wait(REPLY_WINDOW_S)
    replies = [(t, fb) for t, fb in session.feedback(sent[0].t_s) if fb is not None]
    beats = [(t, hb) for t, hb in session.heartbeats(start) if hb is not None and hb.state is RigState.FAULT]
    to_ready(session)
    flagged = [(t, fb) for t, fb in replies if getattr(fb, flag)]
    if not flagged:
        return CheckResult(key, title, rule, f"no reply in {ticks} ms at {drive_v:.2f} V showed the flag", False,
                           {"drive_v": drive_v})
    t_flag, first = flagged[0]
    coded = [hb.fault_code.name for _, hb in beats]
    held_off = not replies[-1][1].amp_enabled
    ok = code.name in coded[:1] and held_off if beats else held_off
    return CheckResult(key, title, rule,
                       f"flagged {(t_flag - sent[0].t_s) * 1e3:.0f} ms into a RUN at {drive_v:.2f} V (rack "
                       f"{first.position_mm:.2f} mm, coil {first.current_a:.2f} A); fault code "
                       f"{coded[0] if coded else 'not announced'}; amplifier {'off' if held_off else 'on'} after",
                       ok, {"drive_v": drive_v, "fault_codes": coded, "after_ms": (t_flag - sent[0].t_s) * 1e3})


__all__ = ["CheckResult", "Expectations", "fault_flags", "heartbeat", "invalid_frames", "replies_and_latency",
           "safe_applies_zero", "samples_before_drive", "to_ready", "valid_command", "watchdog"]
