"""The verdict's parts of a record as typed values: built by :func:`~edc_bench.verdict.judgement.judge_run`, held
by its :class:`~edc_bench.verdict.judgement.Judgement`, written into record.json as they are and read back as the
same models (:mod:`edc_bench.records.schema` assembles them).

A leaf (pydantic and the verdicts' names only), so the record's schema and the report can name these without
reaching into the verdict's rules.
"""

from __future__ import annotations

from typing import Annotated, Any

from pydantic import BeforeValidator, Field

from edc_bench.section import JudgedFeatures, Section
from edc_bench.verdict.baseline_source import BaselineSource
from edc_bench.verdict.verdicts import Verdict


def none_if_empty(value: Any) -> Any:
    """``value``, or None for the "" older records wrote for none (a validator of optional fields)."""
    return None if value == "" else value


#: A verdict a section names, or None where there is none; older records wrote "" for none.
MaybeVerdict = Annotated[Verdict | None, BeforeValidator(none_if_empty)]


class ParameterEstimate(Section):
    """One identified parameter: value, standard error, whether it was estimated; truth on a simulated rig."""

    value: float | None = None
    std: float | None = None
    estimated: bool = False
    truth: float | None = None
    error_rel: float | None = None


class ReferenceValue(Section):
    """The figure a parameter is compared with, and where it comes from (baseline or data sheet)."""

    value: float | None = None
    source: str = ""


class ClassificationSummary(Section):
    """The classifier's judgement of the features, naming the model exactly."""

    verdict: Verdict
    probability_faulty: float
    #: signed distance to the boundary; None: beyond the classifier's scan (3.0), far on its verdict's side (the
    #: classifier's +/-inf, which JSON cannot hold)
    distance: float | None
    features_rel: JudgedFeatures
    model: str = ""
    model_name: str | None = None
    model_file: str | None = None
    model_sha256: str | None = None
    threshold: float | None = None
    marginal_band: float | None = None
    training_data_sha256: str | None = None


class MotionFigure(Section):
    """One motion parameter of a baseline's new-valve tests (a2, a0 or b, referred to the reference coil)."""

    mean: float
    sd: float
    tests: int


class BaselineSummary(Section):
    """The new-valve baseline the features were compared with (figures and provenance; ``motion``: its a2, a0 and
    b, where its tests hold them, for the part diagnosis: schema 11 on)."""

    af_v: float | None = None
    a1_v_s_per_mm: float | None = None
    af_sd_v: float | None = None
    a1_sd_v_s_per_mm: float | None = None
    af_uncertainty_v: float | None = None
    a1_uncertainty_v_s_per_mm: float | None = None
    tests: int = 0
    source: str = ""  # in words, for people
    sources: list[BaselineSource] = Field(default_factory=list)  # where its tests ran (schema 10 on; upgraded)
    calibrated: bool | None = None
    written_at: str | None = None
    station: str | None = None
    software: str | None = None
    path: str | None = None
    motion: dict[str, MotionFigure] | None = None
    #: the pumps its tests ran in (:attr:`~edc_bench.verdict.baseline.Baseline.pumps`: 0 simulated pumps alone, the
    #: type's own spring; None not known; schema 13 on)
    pumps: int | None = None


class DecisionPlane(Section):
    """P(faulty) on a grid of relative features, for the report to draw the boundary without the model."""

    af_rel_range: tuple[float, float]
    a1_rel_range: tuple[float, float]
    p_faulty: list[list[float]]
    threshold: float
    marginal_band: float


class RetestSummary(Section):
    """A retest's record: the test it repeats and what the two decide (:mod:`edc_bench.verdict.retest`)."""

    of_record: str = ""  # the first test's record folder (its name: the two sit side by side)
    of_verdict: MaybeVerdict = None  # the first test's verdict (MARGINAL)
    decision: MaybeVerdict = None  # what the pair decides: PASS, FAIL or INVALID
    words: str = ""  # the technician's line for the pair
    rule: str = ""  # the variant's rule that decided, e.g. "retest.decide.MARGINAL = FAIL"
