"""What a shop's candidate classifier was decided on: its cross-validated figures on the shop's teardown labels
beside the model it was trained to replace (:mod:`edc_bench.learning.shop_training` measures them).

Kept in the candidate's model file (metadata :data:`EVALUATION_KEY`) and, once adopted, in the history's adoption
row (``edc-bench train --adopt``), where the web view's models page shows it. Plain data, no training library: a
station adopting a model and the chain's web server read it without scikit-learn.
"""

from __future__ import annotations

import json
import math
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
        """The evaluation as stored (keys sorted: the same figures, the same text; a figure that is not a number,
        such as the accuracy outside the band when every test was inside it, as null)."""
        return json.dumps({"folds": self.folds, "labels": self.labels, "worn_or_faulty": self.worn_or_faulty,
                           "candidate": _finite(self.candidate.as_dict()), "replaced": _finite(self.replaced.as_dict()),
                           "replaced_sha256": self.replaced_sha256}, sort_keys=True, allow_nan=False)

    @classmethod
    def from_json(cls, text: str | None) -> CandidateEvaluation | None:
        """The evaluation ``text`` holds; None for none, or for text that is not one: a model file's metadata, and
        a row an engineer's login wrote, are whatever their writer put there, so every figure is held to what it
        can be (shares within 0 to 1, counts whole and not negative, at least two folds)."""
        if not text:
            return None
        try:
            found = json.loads(text, parse_constant=_no_constant)
            evaluation = cls(folds=_count(found["folds"], least=2), labels=_count(found["labels"]),
                             worn_or_faulty=_count(found["worn_or_faulty"]), candidate=_score_of(found["candidate"]),
                             replaced=_score_of(found["replaced"]), replaced_sha256=_text(found["replaced_sha256"]))
        except Exception:  # noqa: BLE001 - any text at all: a RecursionError of deep nesting included
            return None
        return evaluation


def _finite(score: dict[str, Any]) -> dict[str, Any]:
    return {key: None if isinstance(value, float) and not math.isfinite(value) else value
            for key, value in score.items()}


def _no_constant(name: str) -> float:
    raise ValueError(f"{name} is no figure")


def _count(value: Any, least: int = 0) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or not least <= value < 10**9:
        raise ValueError(f"{value!r} is no count")
    return value


def _share(value: Any, missing: bool = False) -> float:
    if value is None and missing:
        return math.nan  # none of the tests in the part it counts (stored as null)
    if isinstance(value, bool) or not isinstance(value, int | float) or not 0.0 <= value <= 1.0:
        raise ValueError(f"{value!r} is no share")
    return float(value)


def _text(value: Any) -> str:
    if not isinstance(value, str) or len(value) > 200:
        raise ValueError("no short text")
    return value


def _score_of(found: Any) -> Score:
    if not isinstance(found, dict) or not isinstance(found.get("in_sample", False), bool):
        raise ValueError("a score is a mapping, in_sample true or false")
    return Score(model=_text(found["model"]), tests=_count(found["tests"]), accuracy=_share(found["accuracy"]),
                 marginal=_count(found["marginal"]),
                 accuracy_outside_band=_share(found["accuracy_outside_band"], missing=True),
                 worn_passed=_count(found["worn_passed"]), reusable_failed=_count(found["reusable_failed"]),
                 in_sample=bool(found.get("in_sample", False)))


__all__ = ["EVALUATION_KEY", "CandidateEvaluation", "Score"]
