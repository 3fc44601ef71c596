"""Identification's parts of a record as typed values: the coil's finding and the model fit, built where they are
measured (:func:`~edc_bench.identification.coil_check.coil_finding`,
:meth:`~edc_bench.identification.analysis.ModelFit.summary`) and written into record.json as they are.

A leaf (pydantic only), so the record's schema and the report can name these without reaching into
identification."""

from __future__ import annotations

from pydantic import Field

from edc_bench.section import Section


class CoilFinding(Section):
    """The coil's resistance as the test measured it and its verdict against the spec (None: no spec)."""

    resistance_ohm: float | None = None
    resistance_start_ohm: float | None = None
    resistance_20c_ohm: float | None = None
    temp_start_c: float | None = None
    temp_given: bool = False
    temp_source: str = ""
    warming_k: float | None = None
    spec_ohm: tuple[float | None, float | None] = (None, None)
    in_spec: bool | None = None
    reference_ohm: float | None = None
    inductance_mh: float | None = None
    inductance_source: str = ""


class ModelFitSummary(Section):
    """How well the pump model fits the measurement (and, when it does not, why)."""

    residual_rms_v: float | None = None
    expected_noise_v: float | None = None
    residual_ratio: float | None = None
    systematic_rms_v: float | None = None
    systematic_ratio: float | None = None
    spread_rel: dict[str, float | None] | None = None
    gain_variation_rel: float | None = None
    fits: bool | None = None
    problems: list[str] = Field(default_factory=list)
    core_shift_rel: dict[str, float | None] | None = None
