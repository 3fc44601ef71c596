"""Per-tick compute and per-frame codec cost, each next to its floor.

The floors are the same work with nothing around it: the controller's
shared arithmetic (:mod:`edc_bench.control.law`, the loop's and the batch
path's) called from one closure over local lists, so the tick's figure
beside it is what the loop's design costs beyond that arithmetic; and the
frames packed with :mod:`struct` (same layout, same scaling, same CRC). Each call is timed on its own with
``perf_counter_ns``, so the figures are per-call percentiles, not averages
that hide the tail.
"""

from __future__ import annotations

import struct
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from edc_bench.config.models import EstimatorKind, Variant
from edc_bench.control import law
from edc_bench.control.coil import CoilEstimator
from edc_bench.control.design import ControllerDesign
from edc_bench.control.estimators import MAX_COVARIANCE_TRACE
from edc_bench.control.fel import FelController, reference_table
from edc_bench.perf.figures import percentiles
from edc_bench.protocol import Icd, Mode
from edc_bench.protocol.crc import e2e_crc


def time_calls_ns(fn: Callable[[int], object], count: int) -> np.ndarray:
    """Time ``fn(k)`` for k in 0..count-1, each call on its own (ns)."""
    out = np.empty(count)
    clock = time.perf_counter_ns
    for k in range(count):
        t0 = clock()
        fn(k)
        out[k] = clock() - t0
    return out


def _measured_positions(ctl: FelController, count: int, seed: int = 1) -> list[float]:
    """A plausible measured rack: the reference plus 5 um of noise."""
    rng = np.random.default_rng(seed)
    k = np.arange(count)
    r_now = ctl.reference.tabulate(k * ctl.period_s)[0]
    return (r_now + rng.normal(0.0, 0.005, count)).tolist()


def lean_tick(design: ControllerDesign, start_mm: float) -> Callable[[int, float], float]:
    """The floor: the controller's shared arithmetic (:mod:`edc_bench.control.law`) in one closure, and nothing else.

    Built from the same :class:`ControllerDesign` as the loop's controller (reference table, PID coefficients,
    starting estimates and prior), it calls the same law functions for the PID, the feedforward, the saturation,
    the adaptation gate, the estimator and the coil average, with the one sample each tick brings; what
    :class:`FelController` costs beyond it (samples by tick, averaging several, holding, the trace's figures) is
    the loop design's cost. No coil current comes here: the coil stays at its prior, as in the loop without one.
    """
    reference = design.reference(start_mm)
    table = reference_table(reference, design.period_s, design.ticks)
    ops = law.SCALAR
    pid_c = law.PidCoefficients.of(design.pid_gains, design.period_s, design.drive_limit_v)
    pid = law.PidState()
    rls = design.estimator_kind is EstimatorKind.RLS
    theta = list(design.theta0)
    P = [[s * s if i == j else 0.0 for j, s in enumerate(design.prior_std)] for i in range(len(theta))]
    lam = design.forgetting_factor
    gains_t = [g * design.period_s for g in design.gradient_gains_per_s]
    composition = design.composition()
    coil = CoilEstimator(design.amplifier_gain, design.reference_resistance_ohm, design.period_s)
    coil_average = law.CoilAverage(design.coil_window_ticks, design.reference_resistance_ohm)
    r_ref = design.reference_resistance_ohm
    T = design.period_s
    state = [0, reference.at(0.0)[0]]  # saturated, the reference the next sample is compared with
    w = [0.0] * 6

    def tick(k: int, measured_mm: float) -> float:
        saturated, r_prev = state
        u2 = law.pid_update(ops, pid_c, pid, r_prev - measured_mm, saturated)
        r, r1, r2, r3, r_now = table[k]
        law.regressors(ops, w, r, r1, r2, r3)
        rho = coil_average.add(coil.resistance_ohm) / r_ref
        _, u, saturated, learn, we, fixed_part = law.feedforward_tick(ops, composition, theta, w, u2, rho, k * T)
        if learn:
            if rls:
                law.rls_update(ops, theta, P, we, law.estimator_target(u, rho, fixed_part), lam, MAX_COVARIANCE_TRACE)
            else:
                law.gradient_update(ops, theta, gains_t, we, law.estimator_target(u, rho, fixed_part))
        state[0], state[1] = saturated, r_now
        return u

    return tick


@dataclass(frozen=True)
class TickCost:
    """The controller's per-tick cost and its floor's (us), and how far their drives ever differed (V)."""

    p50_us: float
    p99_us: float
    floor_p50_us: float
    floor_p99_us: float
    max_drive_difference_v: float
    ticks: int


@dataclass(frozen=True)
class FrameCost:
    """One frame operation's cost, p50 (us): the codec's, the struct floor's and cantools'."""

    ours_us: float
    struct_us: float
    cantools_us: float


@dataclass(frozen=True)
class CodecCost:
    """BENCH_CMD's encode and RIG_FEEDBACK's decode, each with its CRC, over ``frames`` frames."""

    encode: FrameCost
    decode: FrameCost
    frames: int


def tick_compute(variant: Variant, count: int) -> TickCost:
    """Per-tick cost of the controller and of its floor (us), for the variant's estimator.

    Both run the same ``count`` ticks from the start of a test, on a rack
    that follows the reference with sensor noise, so the estimator adapts
    from the end of the move on. Their drive outputs are compared: the floor
    must do the same arithmetic.
    """
    design = ControllerDesign.from_variant(variant)
    ctl = design.controller(1.0)
    floor = lean_tick(design, 1.0)
    positions = _measured_positions(ctl, count)
    drives = [0.0] * count
    floor_drives = [0.0] * count

    def real(k: int) -> None:
        drives[k] = ctl.step(k, positions[k])

    def lean(k: int) -> None:
        floor_drives[k] = floor(k, positions[k])

    # interleave short runs of each, so a burst of CPU steal hits both alike
    real_ns, lean_ns = [], []
    chunk = 1000
    step_real = _chunked(real, count, chunk)
    step_lean = _chunked(lean, count, chunk)
    for a, b in zip(step_real, step_lean, strict=True):
        real_ns.append(a)
        lean_ns.append(b)
    real_us = np.concatenate(real_ns) / 1e3
    lean_us = np.concatenate(lean_ns) / 1e3
    mismatch = float(np.max(np.abs(np.array(drives) - np.array(floor_drives))))
    p50, p99 = percentiles(real_us)
    f50, f99 = percentiles(lean_us)
    return TickCost(p50, p99, f50, f99, mismatch, count)


def _chunked(fn: Callable[[int], object], count: int, chunk: int):
    for start in range(0, count, chunk):
        stop = min(start + chunk, count)
        yield time_calls_ns(lambda k, s=start: fn(s + k), stop - start)


def struct_floor(icd: Icd) -> tuple[Callable[..., bytes], Callable[[bytes], tuple]]:
    """BENCH_CMD encode and RIG_FEEDBACK decode with :mod:`struct`: same layout, scaling and CRC.

    The layouts are read from the compiled DBC and must be byte-aligned
    (they are in ICD v1: CRC, counter, mode or flag byte, then 16-bit fields).
    """
    cmd_id, fb_id = icd.bench_cmd_data_id, icd.rig_feedback_data_id
    pack = struct.Struct("<BBBhHx").pack  # crc, counter, mode, drive (mV), reference (um)
    unpack = struct.Struct("<BBBHhx").unpack  # crc, counter, flags, position (um), current (mA)
    _check_byte_layout(icd)

    def encode(counter: int, mode: int, drive_v: float, reference_mm: float) -> bytes:
        body = pack(0, counter, mode, round(drive_v * 1000.0), round(reference_mm * 1000.0))
        return bytes((e2e_crc(cmd_id, body),)) + body[1:]

    def decode(payload: bytes) -> tuple:
        crc, counter, flags, pos, cur = unpack(payload)
        if crc != e2e_crc(fb_id, payload):
            raise ValueError("CRC mismatch")
        return (counter, flags & 1, (flags >> 1) & 1, (flags >> 2) & 1, (flags >> 3) & 1, (flags >> 4) & 1,
                pos * 0.001, cur * 0.001)

    return encode, decode


def _check_byte_layout(icd: Icd) -> None:
    """Refuse to benchmark a floor whose layout no longer matches the DBC."""
    expected = {
        "BENCH_CMD": [(0, 8, 1.0), (8, 8, 1.0), (16, 8, 1.0), (24, 16, 0.001), (40, 16, 0.001)],
        "RIG_FEEDBACK": [(0, 8, 1.0), (8, 8, 1.0), (16, 1, 1.0), (17, 1, 1.0), (18, 1, 1.0), (19, 1, 1.0),
                         (20, 1, 1.0), (24, 16, 0.001), (40, 16, 0.001)],
    }
    for layout in (icd.bench_cmd, icd.rig_feedback):
        got = [(s.start_bit, s.length_bits, s.scale) for s in layout.signals]
        if got != expected[layout.name]:
            raise RuntimeError(f"{layout.name}'s layout changed ({got}); update the struct floor in {__name__}")


def codec(icd: Icd, count: int) -> CodecCost:
    """Per-frame cost (us, p50) of BENCH_CMD encode and RIG_FEEDBACK decode: ours, struct's and cantools'."""
    enc_floor, dec_floor = struct_floor(icd)
    feedback = icd.make_rig_feedback(7, amp_enabled=True, watchdog_tripped=False, over_current=False,
                                     lvdt_fault=False, travel_limit=False, position_mm=12.345, current_a=-0.678)
    if icd.make_bench_cmd(7, Mode.RUN, 1.234, 12.5) != enc_floor(7, Mode.RUN, 1.234, 12.5):
        raise RuntimeError("the struct floor does not encode BENCH_CMD as the codec does")
    cmd_msg = icd.database.get_message_by_name("BENCH_CMD")
    fb_msg = icd.database.get_message_by_name("RIG_FEEDBACK")
    cmd_values = {"CRC": 0, "Counter": 7, "Mode": 1, "DriveVoltage": 1.234, "RackReference": 12.5}

    def cantools_encode(_k: int) -> None:
        body = cmd_msg.encode(cmd_values)
        bytes((e2e_crc(icd.bench_cmd_data_id, body),)) + body[1:]

    def cantools_decode(_k: int) -> None:
        fb_msg.decode(feedback)
        e2e_crc(icd.rig_feedback_data_id, feedback)

    def p50_us(fn: Callable[[int], object]) -> float:
        fn(0)
        return percentiles(time_calls_ns(fn, count) / 1e3, (50,))[0]

    encode = FrameCost(p50_us(lambda _k: icd.make_bench_cmd(7, Mode.RUN, 1.234, 12.5)),
                       p50_us(lambda _k: enc_floor(7, Mode.RUN, 1.234, 12.5)), p50_us(cantools_encode))
    decode = FrameCost(p50_us(lambda _k: icd.parse_rig_feedback(feedback)), p50_us(lambda _k: dec_floor(feedback)),
                       p50_us(cantools_decode))
    return CodecCost(encode, decode, count)
