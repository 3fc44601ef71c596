"""The coil's finding as a record keeps it: a leaf of typed figures (no numpy, no variant), so the record's schema
and the report can name it without reaching into identification."""

from __future__ import annotations

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
