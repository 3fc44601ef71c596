"""What a shop's candidate classifier was decided on: its cross-validated figures on the shop's teardown labels
beside the model it was trained to replace (:mod:`edc_bench.learning.shop_training` measures them).

Kept in the candidate's model file (metadata :data:`EVALUATION_KEY`) and, once adopted, in the history's adoption
row (``edc-bench train --adopt``), where the web view's models page shows it. Plain data, no training library: a
station adopting a model and the chain's web server read it without scikit-learn.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from typing import Any

@dataclass(frozen=True)
class Score:
    """How one model judged a set of labelled tests."""

    model: str
    tests: int
    accuracy: float  # decision at the threshold against the teardown label
    marginal: int  # tests inside the marginal band (a retest on the bench)
    accuracy_outside_band: float
    worn_passed: int  # labelled worn or faulty, judged reusable (outside the band)
    reusable_failed: int  # labelled reusable, judged faulty (outside the band)
    in_sample: bool = False  # the model learnt from shop labels: these figures may be optimistic

    def as_dict(self) -> dict[str, Any]:
        """Plain data for JSON."""
        return dict(self.__dict__)


#: The candidate model's metadata entry holding its :class:`CandidateEvaluation` (JSON).
EVALUATION_KEY = "edc_bench.evaluation"


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
        """The evaluation as stored (keys sorted: the same figures, the same text)."""
        return json.dumps({"folds": self.folds, "labels": self.labels, "worn_or_faulty": self.worn_or_faulty,
                           "candidate": self.candidate.as_dict(), "replaced": self.replaced.as_dict(),
                           "replaced_sha256": self.replaced_sha256}, sort_keys=True)

    @classmethod
    def from_json(cls, text: str | None) -> CandidateEvaluation | None:
        """The evaluation ``text`` holds; None for none, or for text that is not one (a model file's metadata is
        whatever its writer put there)."""
        if not text:
            return None
        try:
            found = json.loads(text)
            evaluation = cls(folds=int(found["folds"]), labels=int(found["labels"]),
                             worn_or_faulty=int(found["worn_or_faulty"]), candidate=_score_of(found["candidate"]),
                             replaced=_score_of(found["replaced"]), replaced_sha256=str(found["replaced_sha256"]))
        except (ValueError, TypeError, KeyError):
            return None
        return evaluation


def _score_of(found: Any) -> Score:
    if not isinstance(found, dict):
        raise TypeError("a score is a mapping")
    return Score(model=str(found["model"]), tests=int(found["tests"]), accuracy=float(found["accuracy"]),
                 marginal=int(found["marginal"]), accuracy_outside_band=float(found["accuracy_outside_band"]),
                 worn_passed=int(found["worn_passed"]), reusable_failed=int(found["reusable_failed"]),
                 in_sample=bool(found.get("in_sample", False)))


__all__ = ["EVALUATION_KEY", "CandidateEvaluation", "Score"]
