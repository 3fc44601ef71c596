"""The base of every typed part of a test's record: frozen once built, and tolerant of a newer edc-bench's keys.

A utility outside the layers (it imports only pydantic): the engine, identification and the verdict build their
parts of a record as these models, and :mod:`edc_bench.records.schema` assembles them into the record, so each part
has one shape from where it is made to record.json and back.
"""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict


class Section(BaseModel):
    """A part of a record: read-only once built; unknown keys (a newer record's) kept, not refused."""

    model_config = ConfigDict(frozen=True, extra="allow")
