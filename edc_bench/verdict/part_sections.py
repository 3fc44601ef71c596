"""The part diagnosis's shape in a record (:func:`~edc_bench.verdict.part.diagnose_parts` builds it): which part of
the fuel-injection module is at fault, and every signature's figure against its limit.

A leaf (pydantic only), so the record's schema, the advice and the report read it without the diagnosis's rules.
"""

from __future__ import annotations

import enum

from edc_bench.section import Section
from edc_bench.verdict.sections import BaselineSummary


class Part(enum.StrEnum):
    """Which part of the fuel-injection module a test finds at fault (the values are what records and the history
    keep)."""

    NONE = "none"  # nothing beyond the valve's own verdict: the rack and the sensor sound
    VALVE_OR_RACK = "valve or rack"  # friction above a new valve's, the same along the stroke: cannot be told apart
    RACK = "rack"  # the control rack binds or drags unevenly
    SENSOR = "rack-travel sensor"  # the sensor's reading is off, noisy or drops out
    NOT_JUDGED = "valve only judged"  # a record from before the part diagnosis


class Signature(enum.StrEnum):
    """What one finding measured."""

    SENSOR_DROPOUTS = "sensor dropouts"
    SENSOR_SPIKES = "sensor spikes"
    SENSOR_NOISE = "sensor noise"
    SENSOR_ZERO = "sensor zero"
    SENSOR_GAIN = "sensor gain"
    SENSOR_LINEARITY = "sensor linearity"
    SENSOR_UNEVEN = "sensor uneven"
    SPRING_RATE = "spring rate"
    RACK_BIND = "rack bind"
    RACK_SLOPE = "rack friction slope"
    UNIFORM_FRICTION = "uniform friction"


class PartFinding(Section):
    """One signature against its limit.

    Attributes
    ----------
    signature : Signature
    part : Part
        The part it points at when beyond its limit.
    figure, limit : float
        The measured figure and its limit, in ``unit`` (an empty unit: a share, of the new-valve friction af0 for the
        rack's figures, of the baseline's for the sensor's gain).
    beyond : bool
        The figure is beyond its limit (and clear of its uncertainty).
    std : float or None
        The figure's standard error, where known.
    at_mm : float or None
        Where along the stroke (a bind).
    """

    signature: Signature
    part: Part
    figure: float | None
    limit: float
    unit: str = ""
    beyond: bool = False
    std: float | None = None
    at_mm: float | None = None


class FrictionProfileSummary(Section):
    """The friction along the swing (:class:`~edc_bench.identification.signatures.FrictionProfile`)."""

    positions_mm: list[float]
    friction_v: list[float]
    std_v: list[float]
    gain_slope_per_mm: float
    periods: int


class ReadingSummary(Section):
    """The rack-travel sensor's reading (:class:`~edc_bench.identification.signatures.ReadingStatistics`)."""

    rest_mm: float | None = None
    noise_mm: float | None = None
    expected_noise_mm: float | None = None
    spikes: int = 0
    dropouts: int = 0


class PartDiagnosis(Section):
    """The record's ``part`` section: the part at fault and the evidence.

    Attributes
    ----------
    part : Part
    valve_judged : bool
        The valve's verdict stands (False where the rack or the sensor biases its figures).
    findings : list of PartFinding
        Every signature measured, beyond its limit or not.
    friction_profile : FrictionProfileSummary or None
    reading : ReadingSummary or None
    not_identified : list of str
        What this test's excitation does not identify.
    compared_with : BaselineSummary or None
        The new-valve baseline the figures were held to (its af, a2, a0 and b), also where the valve was not
        judged; replay compares with it again.
    """

    part: Part
    valve_judged: bool = True
    findings: list[PartFinding] = []
    friction_profile: FrictionProfileSummary | None = None
    reading: ReadingSummary | None = None
    not_identified: list[str] = []
    compared_with: BaselineSummary | None = None

    @property
    def beyond(self) -> list[PartFinding]:
        """The findings beyond their limits that point at a part (the spring's rate, which is no fault, left out)."""
        return [f for f in self.findings if f.beyond and f.part is not Part.NONE]

    def finding(self, signature: Signature) -> PartFinding | None:
        """The finding of one signature, if measured."""
        return next((f for f in self.findings if f.signature is signature), None)


#: What older records say (read back as this: the valve alone was judged).
VALVE_ONLY = PartDiagnosis(part=Part.NOT_JUDGED)

