"""A candidate's evaluation as stored in its model file and in the history's adoption row: whatever a file's author
or an engineer's login wrote there is read as an evaluation only if every figure is one it can be."""

from __future__ import annotations

import json
import math

import pytest

from edc_bench.learning.candidate_evaluation import CandidateEvaluation, Score


def _evaluation(outside_band: float = 0.95) -> CandidateEvaluation:
    return CandidateEvaluation(5, 120, 40, Score("shop-1 (cross-validated)", 120, 0.93, 6, outside_band, 2, 3),
                               Score("p-edc-default", 120, 0.81, 9, 0.84, 13, 4, in_sample=False), "a" * 64)


def test_an_evaluation_reads_back_as_written_a_share_of_no_tests_as_null() -> None:
    assert CandidateEvaluation.from_json(_evaluation().to_json()) == _evaluation()
    none_outside = _evaluation(outside_band=math.nan)  # every test inside the marginal band
    text = none_outside.to_json()
    assert "NaN" not in text and json.loads(text)["candidate"]["accuracy_outside_band"] is None
    read = CandidateEvaluation.from_json(text)
    assert read is not None and math.isnan(read.candidate.accuracy_outside_band)


def _with(path: tuple[str, ...], value: object) -> str:
    doc = json.loads(_evaluation().to_json())
    inner = doc
    for key in path[:-1]:
        inner = inner[key]
    inner[path[-1]] = value
    return json.dumps(doc)


HOSTILE = [
    "", "[", "null", "[]", '"text"', "{}", "[" * 100_000 + "]" * 100_000,
    _with(("folds",), 1e999), _with(("folds",), "five"), _with(("folds",), 1), _with(("folds",), True),
    _with(("labels",), -3), _with(("labels",), 10**30), _with(("labels",), 2.5),
    _with(("candidate", "accuracy"), 1e300), _with(("candidate", "accuracy"), -0.1),
    _with(("candidate", "accuracy"), "93 %"), _with(("candidate",), [1, 2]),
    _with(("replaced", "in_sample"), "false"), _with(("replaced", "model"), "x" * 10_000),
    _with(("replaced_sha256",), None),
    _evaluation().to_json().replace("0.93", "NaN"), _evaluation().to_json().replace("0.93", "Infinity"),
]


@pytest.mark.parametrize("text", HOSTILE, ids=[str(n) for n in range(len(HOSTILE))])
def test_text_that_is_no_evaluation_reads_as_none(text: str) -> None:
    assert CandidateEvaluation.from_json(text) is None
