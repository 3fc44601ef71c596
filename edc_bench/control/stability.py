"""Check a variant's PID gains against its nominal plant (python-control).

The loop analysed is the one the bench runs: the plant discretised with a
zero-order hold at the tick period, one period of delay (the rack sample
used at tick k was taken at tick k-1, docs/method.md section 4), and the discrete PID with
its filtered derivative exactly as :class:`~edc_bench.control.pid.Pid`
computes it. Friction is left out (the nominal plant is the linear one).
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from typing import TYPE_CHECKING

from edc_bench.config.models import Variant
from edc_bench.control.law import derivative_filter_coefficients
from edc_bench.control.pid import PidGains
from edc_bench.errors import ConfigError
from edc_bench.physics.parameters import PlantParameters

if TYPE_CHECKING:
    import control


@dataclass(frozen=True)
class LoopMargins:
    """Stability margins of the bench's feedback loop.

    Attributes
    ----------
    gain_margin_db : float
        Gain margin (inf if the phase never crosses -180 degrees).
    phase_margin_deg : float
        Phase margin (inf if the gain never crosses 1).
    crossover_hz : float
        Gain crossover frequency (nan if none): the loop's bandwidth.
    closed_loop_stable : bool
        All closed-loop poles strictly inside the unit circle.
    max_pole_radius : float
        Largest closed-loop pole magnitude.
    """

    gain_margin_db: float
    phase_margin_deg: float
    crossover_hz: float
    closed_loop_stable: bool
    max_pole_radius: float
    delay_ticks: int = 1


def delayed_plant(params: PlantParameters, period_s: float, delay_ticks: int = 1) -> control.TransferFunction:
    """Drive (V) to rack position (mm) as the loop sees it: coil and rack, zero-order hold, ``delay_ticks`` of delay.

    Friction is left out (the nominal plant is the linear one).
    """
    import control

    p = params
    gain = p.amplifier_gain * p.force_constant_n_per_a
    coil = control.tf([gain], [p.inductance_h, p.resistance_ohm])
    mech = control.tf([1.0], [p.mass_n_s2_per_mm, p.damping_n_s_per_mm, p.net_stiffness_n_per_mm])
    plant_d = control.c2d(coil * mech, period_s, method="zoh")
    return plant_d * control.tf([1.0], [1.0] + [0.0] * max(1, delay_ticks), period_s)  # z^-delay


def discrete_pid(kp: float, ki: float, kd: float, derivative_filter_hz: float,
                 period_s: float) -> control.TransferFunction:
    """The PID exactly as :class:`~edc_bench.control.pid.Pid` computes it, error (mm) to drive (V)."""
    import control

    z = control.tf([1.0, 0.0], [1.0], period_s)
    a, b = derivative_filter_coefficients(PidGains(kp, ki, kd, derivative_filter_hz), period_s)
    return kp + ki * period_s * z / (z - 1) + b * (z - 1) / (z - a)


def loop_margins(params: PlantParameters, kp: float, ki: float, kd: float, derivative_filter_hz: float,
                 period_s: float, delay_ticks: int = 1) -> LoopMargins:
    """Margins of PID + transport delay + ZOH plant.

    Parameters
    ----------
    params : PlantParameters
        Plant (friction ignored).
    kp, ki, kd : float
        PID gains (V/mm, V/(mm s), V s/mm).
    derivative_filter_hz : float
        Derivative filter corner.
    period_s : float
        Tick period.
    delay_ticks : int, optional
        Ticks between a sample and the drive computed from it taking effect:
        1 when every reply comes within its tick; the oldest reply age the
        loop may use, in ticks, with a USB adapter's latency.

    Returns
    -------
    LoopMargins
    """
    import control  # heavy (about 1.5 s): imported only when a check runs

    loop = discrete_pid(kp, ki, kd, derivative_filter_hz, period_s) * delayed_plant(params, period_s, delay_ticks)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        gm, pm, _, _, wgc = control.stability_margins(loop, method="poly")[:5]
    closed = control.feedback(loop, 1)
    radius = max(abs(complex(pole)) for pole in closed.poles())
    gm_db = 20.0 * math.log10(gm) if gm and math.isfinite(gm) and gm > 0 else math.inf
    return LoopMargins(
        gain_margin_db=gm_db,
        phase_margin_deg=float(pm) if pm is not None and math.isfinite(pm) else math.inf,
        crossover_hz=float(wgc) / (2 * math.pi) if wgc is not None and math.isfinite(wgc) else math.nan,
        closed_loop_stable=radius < 1.0,
        max_pole_radius=radius,
        delay_ticks=max(1, delay_ticks),
    )


def refuse_poor_margins(variant: Variant, m: LoopMargins, variant_argument: str | None = None) -> LoopMargins:
    """Refuse gains that are unstable or marginal on the variant's nominal plant.

    Parameters
    ----------
    variant : Variant
        Supplies the gains (for the message) and the minimum margins.
    m : LoopMargins
        The margins of the variant's loop on its nominal plant.
    variant_argument : str, optional
        How the command line names the variant (its name, or its file), for the ``edc-bench tune`` hint.

    Returns
    -------
    LoopMargins
        ``m``, when the margins are enough.

    Raises
    ------
    ConfigError
        Naming the margins found and the minimums the variant asks for.
    """
    c = variant.controller
    if not m.closed_loop_stable:
        raise ConfigError(
            f"variant {variant.name}: PID gains kp={c.kp_v_per_mm}, ki={c.ki_v_per_mm_s}, kd={c.kd_v_s_per_mm} "
            f"make the loop unstable on the nominal plant with {m.delay_ticks} ticks of transport delay (closed-loop "
            f"pole at radius {m.max_pole_radius:.3f}); {_retune_hint(variant_argument or variant.name)}"
        )
    if m.gain_margin_db < c.min_gain_margin_db or m.phase_margin_deg < c.min_phase_margin_deg:
        raise ConfigError(
            f"variant {variant.name}: PID gains leave too little margin on the nominal plant with {m.delay_ticks} "
            f"ticks of transport delay (acceptance.max_reply_age_ms): gain margin "
            f"{m.gain_margin_db:.1f} dB (need {c.min_gain_margin_db:g}), phase margin {m.phase_margin_deg:.1f} deg "
            f"(need {c.min_phase_margin_deg:g}); {_retune_hint(variant_argument or variant.name)}"
        )
    return m


def _retune_hint(variant_argument: str) -> str:
    return (f"'edc-bench tune --variant {variant_argument}' proposes gains that keep the margins "
            "(add --write to put them into the variant file)")
