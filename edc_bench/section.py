"""The base of every typed part of a test's record: frozen once built, and tolerant of a newer edc-bench's keys.

A utility outside the layers (it imports only pydantic): the engine, identification and the verdict build their
parts of a record as these models, and :mod:`edc_bench.records.schema` assembles them into the record, so each part
has one shape from where it is made to record.json and back. :class:`FeaturePair` (af and a1) is the one shape of
the valve's two features wherever a layer holds them.
"""

from __future__ import annotations

import math

from pydantic import BaseModel, ConfigDict


class Section(BaseModel):
    """A part of a record: read-only once built; unknown keys (a newer record's) kept, not refused."""

    model_config = ConfigDict(frozen=True, extra="allow")


class FeaturePair(Section):
    """af and a1, a valve's two features (friction and damping): in the unit of the field that holds them (V and
    V s/mm, or over the new-valve baseline).

    None where no figure is held (a record's null); a test that did not identify a figure holds NaN (written as
    null: JSON has no NaN).
    """

    af: float | None = None
    a1: float | None = None

    @property
    def identified(self) -> bool:
        """Both figures are numbers (neither None nor NaN nor infinite)."""
        return all(value is not None and math.isfinite(value) for value in (self.af, self.a1))

    def numbers(self) -> tuple[float, float]:
        """(af, a1), a missing figure as NaN."""
        return (math.nan if self.af is None else self.af, math.nan if self.a1 is None else self.a1)


class JudgedFeatures(FeaturePair):
    """af and a1 as a classifier judged them (relative to the baseline): both always figures, so a record's null
    is refused with the field's name, as any figure of the wrong type is."""

    af: float
    a1: float
