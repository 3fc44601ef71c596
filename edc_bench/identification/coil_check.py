"""The coil as a finding of its own: its resistance measured in the test, referred to 20 degC, against its spec.

The loop measured the coil's resistance tick by tick (the trace's
``coil_resistance_ohm``). The coil warms while it works (copper: +0.39 %
per kelvin), so the figure that compares with the manufacturer's spec, or
with a multimeter on a cold coil, is the one at the start of the test,
referred to 20 degC with the coil's temperature then:

- ``R_start``: a straight line through the measurement over the excitation
  (the warming is steady over a test: its time constant is minutes),
  evaluated at the start of the test, and moved by the measurement's lag
  (its memory, 0.5 s, plus half the averaging window, 1 s by default);
- ``R_20 = R_start / (1 + alpha (T_start - 20 degC))``, with ``T_start``
  the coil's temperature at the start: given by the technician
  (``--coil-temp-c``, e.g. a coil warm from earlier tests) or assumed to be
  the workshop's 20 degC (a coil that has rested);
- the warming during the test, ``(R_end / R_start - 1) / alpha``.

A coil is out of spec when ``R_20`` is outside the spec by more than the
measurement's tolerance (1 %).

Pure numpy on the trace.
"""

from __future__ import annotations

import math
import numpy as np

from edc_bench.config.models import Variant
from edc_bench.control.coil import measurement_lag_s
from edc_bench.identification.sections import CoilFinding
from edc_bench.physics.coil import REFERENCE_TEMP_C, resistance_20c_ohm

#: Below this much excitation time the coil's figure is not given.
MIN_MEASURED_S = 2.0
#: A coil is out of spec only beyond this: the measurement's own error (within 0.4 % of the simulated coil
#: over the coils and temperatures of tests/identification/test_coil.py), so a coil at the spec's edge is not scrapped.
SPEC_TOLERANCE_REL = 0.01


def coil_finding(variant: Variant, trace: dict[str, np.ndarray], coil_temp_c: float | None) -> CoilFinding | None:
    """The coil's resistance measured in the test, and whether it is within the variant's spec.

    Parameters
    ----------
    variant : Variant
        Supplies the coil spec (``coil.resistance_min_ohm``/``resistance_max_ohm`` at 20 degC) and alpha.
    trace : dict of numpy.ndarray
        The filled trace (``t_s``, ``coil_resistance_ohm``, ``gap``).
    coil_temp_c : float or None
        The coil's temperature at the start of the test; None: assumed at 20 degC.

    Returns
    -------
    CoilFinding or None
        None if the test ran too briefly to measure the coil.
    """
    coil = variant.coil
    start_s = variant.excitation.move_s + variant.excitation.fade_s
    t = np.asarray(trace.get("t_s", []), dtype=float)
    r = np.asarray(trace.get("coil_resistance_ohm", []), dtype=float)
    keep = (t >= start_s) & np.isfinite(r)
    if "gap" in trace:
        keep &= ~np.asarray(trace["gap"], dtype=bool)
    if not keep.any() or t[keep][-1] - start_s < MIN_MEASURED_S:
        return None
    slope, intercept = np.polyfit(t[keep], r[keep], 1)
    # the loop's figure at time t is the coil's of a little earlier
    lag_s = measurement_lag_s(tone.frequency_hz for tone in variant.excitation.active_tones)
    r_start, r_end = float(intercept + slope * lag_s), float(r[keep][-1] + slope * lag_s)
    alpha = coil.temperature_coefficient_per_k
    temp_c = REFERENCE_TEMP_C if coil_temp_c is None else float(coil_temp_c)
    r20 = float(resistance_20c_ohm(r_start, temp_c, alpha))
    low, high = coil.resistance_min_ohm, coil.resistance_max_ohm
    return CoilFinding(
        resistance_ohm=r_end,
        resistance_start_ohm=r_start,
        resistance_20c_ohm=r20,
        temp_start_c=temp_c,
        temp_given=coil_temp_c is not None,
        temp_source="given (--coil-temp-c)" if coil_temp_c is not None else "assumed: a rested coil at 20 degC",
        warming_k=(r_end / r_start - 1.0) / alpha if alpha > 0 and r_start > 0 else math.nan,
        spec_ohm=(low, high),
        in_spec=in_spec(r20, low, high),
        reference_ohm=coil.resistance_ohm,
        inductance_mh=coil.inductance_mh,
        inductance_source="nominal (not measured)",
    )


def in_spec(resistance_20c_ohm: float, low: float | None, high: float | None) -> bool | None:
    """Whether a coil's resistance at 20 degC is within its spec ``low``-``high`` ohm (either may be None), beyond
    the measurement's tolerance (:data:`SPEC_TOLERANCE_REL`); None where the variant gives no spec.

    The one place the rule is written: :func:`coil_finding` judges with it, and
    :mod:`edc_bench.records.consistency` re-decides a record's ``coil.in_spec`` with it.
    """
    if low is None and high is None:
        return None
    tol = SPEC_TOLERANCE_REL
    return bool((low is None or resistance_20c_ohm >= low * (1 - tol))
                and (high is None or resistance_20c_ohm <= high * (1 + tol)))


def coil_reason(finding: CoilFinding) -> str | None:
    """The reason a coil fails its spec, in words a technician acts on (None if it does not)."""
    if finding.in_spec is not False or finding.resistance_20c_ohm is None:
        return None
    low, high = finding.spec_ohm
    spec = spec_text(low, high)
    side = "high" if high is not None and finding.resistance_20c_ohm > high else "low"
    hint = ("an open strand, a corroded connector or a poor lead contact reads high; so does a coil warmer than "
            "stated (give its temperature with --coil-temp-c)") if side == "high" else \
        "shorted turns read low"
    return (f"coil out of spec: {finding.resistance_20c_ohm:.3f} ohm at 20 degC (spec {spec}; measured "
            f"{finding.resistance_start_ohm:.3f} ohm at {finding.temp_start_c:g} degC, "
            f"{finding.temp_source}): check the coil and its leads with a multimeter; {hint}")


def spec_text(low: float | None, high: float | None) -> str:
    """A coil spec in words: ``0.6-0.9 ohm``, or one side of it (``>= 0.6 ohm``, ``<= 0.9 ohm``)."""
    if low is not None and high is not None:
        return f"{low:g}-{high:g} ohm"
    return f">= {low:g} ohm" if low is not None else f"<= {high:g} ohm"


def coil_line(finding: CoilFinding | None) -> str:
    """One line for the technician: the coil's resistance at 20 degC, its spec and its warming in the test."""
    if finding is None or finding.resistance_20c_ohm is None:
        return "not measured (the test ran too briefly)"
    low, high = finding.spec_ohm
    spec = "no spec in the variant" if finding.in_spec is None else (
        f"spec {spec_text(low, high)}: {'in spec' if finding.in_spec else 'OUT OF SPEC'}")
    assumed = "" if finding.temp_given else ", coil assumed at 20 degC at the start"
    # a record read back holds a figure it could not measure (NaN) as None
    warming_k, end_ohm = (math.nan if v is None else v for v in (finding.warming_k, finding.resistance_ohm))
    return (f"{finding.resistance_20c_ohm:.3f} ohm at 20 degC ({spec}{assumed}); warmed "
            f"{warming_k:+.1f} K in the test, {end_ohm:.3f} ohm at the end")
