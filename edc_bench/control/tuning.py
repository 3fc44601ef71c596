"""Propose PID gains for a variant's nominal plant: the most bandwidth that keeps the margins.

The loop is the one the gain check analyses (:mod:`edc_bench.control.stability`):
coil and rack behind a zero-order hold, the transport delay in ticks, and
the discrete PID with its filtered derivative exactly as the bench runs it.

The search is loop shaping over a family of PIDs written in series form
around a chosen gain crossover ``w_c``::

    ki = kp w_c / alpha      (integral corner a factor alpha below w_c; alpha < 1: integral-dominated)
    kd = kp beta / w_c       (derivative lead, beta = 0 for PI)
    derivative filter at N x f_c (capped below Nyquist)

For every ``(f_c, alpha, beta, N)`` on a grid, ``kp`` is the gain that puts
the crossover at ``f_c``. The margins of each candidate are read from the
loop's frequency response (python-control evaluates the plant once; the PID
is a closed form); the candidates that keep the margins (with a small reserve
for the grid) are ranked by crossover, rounded to three significant digits,
and checked exactly with :func:`~edc_bench.control.stability.loop_margins`
until one passes. Pure: no files, no clock.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass

import numpy as np

from edc_bench.control.law import derivative_filter_coefficients
from edc_bench.control.pid import PidGains
from edc_bench.control.stability import LoopMargins, delayed_plant, discrete_pid, loop_margins
from edc_bench.errors import ConfigError
from edc_bench.physics.parameters import PlantParameters

#: The grid of the search (see the module docstring).
CROSSOVER_POINTS = 80
#: below 1: integral-dominated PIs, which a long transport delay ahead of the rack's resonance needs
INTEGRAL_RATIOS = (0.1, 0.3, 1.0, 2.0, 3.0, 5.0, 8.0, 15.0)
DERIVATIVE_LEADS = (0.0, 0.2, 0.4, 0.7, 1.0, 1.5, 2.5, 4.0)
FILTER_RATIOS = (2.0, 4.0, 8.0)
#: Reserve kept on the grid's margins, so that the exact check (and rounding) rarely undoes a candidate.
RESERVE_DB, RESERVE_DEG = 0.3, 1.0
#: Settling band of the expected step response.
SETTLING_BAND = 0.02


@dataclass(frozen=True)
class TunedGains:
    """Gains proposed by :func:`tune_pid`, with what they give on the nominal plant.

    Attributes
    ----------
    gains : PidGains
        Proportional, integral, derivative gain and the derivative filter's corner.
    margins : LoopMargins
        Exact margins of the loop with these gains (with the transport delay).
    closed_loop_bandwidth_hz : float
        Where the reference-to-rack response falls 3 dB below its low-frequency value.
    settling_s : float
        Time for a reference step to settle within 2 % (linear plant, no feedforward).
    overshoot_pct : float
        The step response's overshoot.
    """

    gains: PidGains
    margins: LoopMargins
    closed_loop_bandwidth_hz: float
    settling_s: float
    overshoot_pct: float


def _significant(value: float, digits: int = 3) -> float:
    if value == 0 or not math.isfinite(value):
        return value
    return float(f"{value:.{digits}g}")


def _grid_margins(loop: np.ndarray, w: np.ndarray) -> tuple[float, float, float]:
    """Gain margin (dB), phase margin (deg) and last gain crossover (rad/s) from a sampled frequency response."""
    mag = np.abs(loop)
    phase_deg = np.degrees(np.unwrap(np.angle(loop)))
    above = mag >= 1.0
    gain_cross = np.nonzero(above[:-1] != above[1:])[0]
    pm = min(((180.0 + phase_deg[i]) % 360.0 for i in gain_cross), default=math.inf)
    turns = np.floor((phase_deg + 180.0) / 360.0)  # changes where the phase passes -180 (mod 360)
    phase_cross = np.nonzero(turns[:-1] != turns[1:])[0]
    gm = min((-20.0 * math.log10(max(mag[i], 1e-300)) for i in phase_cross), default=math.inf)
    return gm, pm, float(w[gain_cross[-1]]) if len(gain_cross) else math.nan


def _closed_loop_bandwidth_rad_s(loop: np.ndarray, w: np.ndarray) -> float:
    """First frequency where the reference-to-rack response falls 3 dB below its low-frequency value."""
    response = np.abs(loop / (1.0 + loop))
    below = np.nonzero(response < response[0] / math.sqrt(2.0))[0]
    return float(w[below[0]]) if len(below) else float(w[-1])


def step_figures(params: PlantParameters, gains: PidGains, period_s: float,
                 delay_ticks: int) -> tuple[float, float, float]:
    """Closed-loop -3 dB bandwidth (Hz), 2 % settling time (s) and overshoot (%) of a reference step."""
    import control

    loop = discrete_pid(gains.kp_v_per_mm, gains.ki_v_per_mm_s, gains.kd_v_s_per_mm, gains.derivative_filter_hz,
                        period_s) * delayed_plant(params, period_s, delay_ticks)
    closed = control.feedback(loop, 1)
    w = np.logspace(math.log10(2 * math.pi * 0.02), math.log10(math.pi / period_s * 0.999), 4000)
    bandwidth_hz = _closed_loop_bandwidth_rad_s(np.asarray(loop(np.exp(1j * w * period_s))), w) / (2 * math.pi)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        info = control.step_info(closed, SettlingTimeThreshold=SETTLING_BAND)
    return bandwidth_hz, float(info["SettlingTime"]), float(info["Overshoot"])


def tune_pid(params: PlantParameters, period_s: float, delay_ticks: int, min_gain_margin_db: float,
             min_phase_margin_deg: float) -> TunedGains:
    """PID gains with the most closed-loop bandwidth that keep both margins on ``params``.

    Parameters
    ----------
    params : PlantParameters
        The nominal plant (friction is ignored).
    period_s : float
        The loop's tick period.
    delay_ticks : int
        Transport delay of the loop in ticks (1 when replies come within their tick).
    min_gain_margin_db, min_phase_margin_deg : float
        The margins to keep.

    Returns
    -------
    TunedGains

    Raises
    ------
    ConfigError
        If no gains on the grid keep the margins (a plant that the bench's PID cannot hold).
    """
    plant = delayed_plant(params, period_s, delay_ticks)
    nyquist_rad_s = math.pi / period_s
    w = np.logspace(math.log10(2 * math.pi * 0.02), math.log10(nyquist_rad_s * 0.999), 4000)
    z = np.exp(1j * w * period_s)
    plant_response = np.asarray(plant(z))
    candidates: list[tuple[float, PidGains]] = []
    for fc_hz in np.logspace(math.log10(0.05), math.log10(0.25 / period_s), CROSSOVER_POINTS):
        wc = 2 * math.pi * fc_hz
        at = int(np.argmin(np.abs(w - wc)))
        for alpha in INTEGRAL_RATIOS:
            for beta in DERIVATIVE_LEADS:
                for ratio in FILTER_RATIOS if beta > 0 else FILTER_RATIOS[:1]:
                    filter_hz = min(ratio * fc_hz, 0.45 / period_s)
                    unit = _pid_response(PidGains(1.0, wc / alpha, beta / wc, filter_hz), z, period_s)
                    kp = 1.0 / abs(plant_response[at] * unit[at])
                    gains = PidGains(kp, kp * wc / alpha, kp * beta / wc, filter_hz)
                    loop = plant_response * unit * kp
                    gm, pm, crossover = _grid_margins(loop, w)
                    if gm >= min_gain_margin_db + RESERVE_DB and pm >= min_phase_margin_deg + RESERVE_DEG \
                            and math.isfinite(crossover):
                        candidates.append((_closed_loop_bandwidth_rad_s(loop, w), gains))
    candidates.sort(key=lambda item: -item[0])
    for _, raw in candidates[:50]:
        gains = PidGains(*(_significant(v) for v in (raw.kp_v_per_mm, raw.ki_v_per_mm_s, raw.kd_v_s_per_mm,
                                                    raw.derivative_filter_hz)))
        margins = loop_margins(params, gains.kp_v_per_mm, gains.ki_v_per_mm_s, gains.kd_v_s_per_mm,
                               gains.derivative_filter_hz, period_s, delay_ticks)
        if margins.closed_loop_stable and margins.gain_margin_db >= min_gain_margin_db \
                and margins.phase_margin_deg >= min_phase_margin_deg:
            bandwidth_hz, settling_s, overshoot = step_figures(params, gains, period_s, delay_ticks)
            return TunedGains(gains, margins, bandwidth_hz, settling_s, overshoot)
    raise ConfigError(
        f"no PID gains keep {min_gain_margin_db:g} dB and {min_phase_margin_deg:g} deg of margin on this plant with "
        f"{delay_ticks} ticks of transport delay: check the variant's physics, or lower "
        "acceptance.max_reply_age_ms (a faster adapter) or the margins asked for in [controller]")


def _pid_response(gains: PidGains, z: np.ndarray, period_s: float) -> np.ndarray:
    """The discrete PID's frequency response at the points ``z`` on the unit circle (as :func:`discrete_pid`)."""
    a, b = derivative_filter_coefficients(gains, period_s)
    return gains.kp_v_per_mm + gains.ki_v_per_mm_s * period_s * z / (z - 1) + b * (z - 1) / (z - a)
