"""What a shop's candidate classifier was decided on: its cross-validated figures on the shop's teardown labels
beside the model it was trained to replace (:mod:`edc_bench.learning.shop_training` measures them).

Kept in the candidate's model file (metadata :data:`EVALUATION_KEY`) and, once adopted, in the history's adoption
row (``edc-bench train --adopt``), where the web view's models page shows it. Plain data, no training library: a
station adopting a model and the chain's web server read it without scikit-learn.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from pydantic import BaseModel, ConfigDict, Field, ValidationError


@dataclass(frozen=True)
class Score:
    """How one model judged a set of labelled tests."""

    model: str
    tests: int
    accuracy: float  # decision at the threshold against the teardown label
    marginal: int  # tests inside the marginal band (a retest on the bench)
    accuracy_outside_band: float  # NaN: every test was inside the band
    worn_passed: int  # labelled worn or faulty, judged reusable (outside the band)
    reusable_failed: int  # labelled reusable, judged faulty (outside the band)
    in_sample: bool = False  # the model learnt from shop labels: these figures may be optimistic

    def as_dict(self) -> dict[str, Any]:
        """Plain data for JSON."""
        return dict(self.__dict__)


#: The candidate model's metadata entry holding its :class:`CandidateEvaluation` (JSON).
EVALUATION_KEY = "edc_bench.evaluation"

_COUNT = Field(ge=0, lt=10**9)
_SHARE = Field(ge=0.0, le=1.0)


class _StoredScore(BaseModel):
    """A :class:`Score` as stored: each figure held to what it can be (a file's metadata, or a row an engineer's
    login wrote, is whatever its writer put there)."""

    model_config = ConfigDict(frozen=True, strict=True, allow_inf_nan=False, extra="ignore")

    model: str = Field(max_length=200)
    tests: int = _COUNT
    accuracy: float = _SHARE
    marginal: int = _COUNT
    accuracy_outside_band: float | None = _SHARE  # None: every test was inside the band
    worn_passed: int = _COUNT
    reusable_failed: int = _COUNT
    in_sample: bool = False

    @classmethod
    def of(cls, score: Score) -> _StoredScore:
        outside = float(score.accuracy_outside_band)
        # numpy's figures as Python's (a strict model takes no numpy integer)
        return cls(model=str(score.model), tests=int(score.tests), accuracy=float(score.accuracy),
                   marginal=int(score.marginal), accuracy_outside_band=None if math.isnan(outside) else outside,
                   worn_passed=int(score.worn_passed), reusable_failed=int(score.reusable_failed),
                   in_sample=bool(score.in_sample))

    def score(self) -> Score:
        outside = math.nan if self.accuracy_outside_band is None else self.accuracy_outside_band
        return Score(**{**self.model_dump(), "accuracy_outside_band": outside})


class _StoredEvaluation(BaseModel):
    """A :class:`CandidateEvaluation` as stored (JSON)."""

    model_config = ConfigDict(frozen=True, strict=True, allow_inf_nan=False, extra="ignore")

    folds: int = Field(ge=2, lt=1000)
    labels: int = _COUNT
    worn_or_faulty: int = _COUNT
    candidate: _StoredScore
    replaced: _StoredScore
    replaced_sha256: str = Field(max_length=64)


@dataclass(frozen=True)
class CandidateEvaluation:
    """A candidate's cross-validated figures on the shop's labels beside the model it was trained to replace: kept
    in the candidate's file (metadata :data:`EVALUATION_KEY`) and, once adopted, in the history's adoption row, so
    the chain sees what each adoption was decided on."""

    folds: int
    labels: int
    worn_or_faulty: int
    candidate: Score
    replaced: Score
    replaced_sha256: str

    def to_json(self) -> str:
        """The evaluation as stored (a share of no tests, NaN, as null)."""
        return _StoredEvaluation(folds=self.folds, labels=self.labels, worn_or_faulty=self.worn_or_faulty,
                                 candidate=_StoredScore.of(self.candidate), replaced=_StoredScore.of(self.replaced),
                                 replaced_sha256=self.replaced_sha256).model_dump_json()

    @classmethod
    def from_json(cls, text: str | None) -> CandidateEvaluation | None:
        """The evaluation ``text`` holds; None for none, or for text that is not one (shares within 0 to 1, counts
        whole and not negative, at least two folds, nothing that is not a number)."""
        if not text:
            return None
        try:
            stored = _StoredEvaluation.model_validate_json(text)
        except (ValidationError, ValueError, RecursionError):
            return None
        return cls(stored.folds, stored.labels, stored.worn_or_faulty, stored.candidate.score(),
                   stored.replaced.score(), stored.replaced_sha256)


__all__ = ["EVALUATION_KEY", "CandidateEvaluation", "Score"]
