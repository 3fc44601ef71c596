"""How a classifier does on labelled data: its verdicts against the truth."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from edc_bench.config import load_variant
from edc_bench.learning.dataset import Dataset
from edc_bench.verdict.classifier import ValveClassifier, judge_of
from edc_bench.verdict.verdicts import Verdict


@dataclass(frozen=True)
class VerdictCounts:
    """Verdicts against the truth: the MARGINAL share, the accuracy outside the band, and the errors.

    Attributes
    ----------
    marginal : int
        Verdicts MARGINAL.
    marginal_fraction : float
        Their share of the verdicts (NaN when there are none).
    accuracy_outside_band : float
        Of the verdicts outside the marginal band, the share that agrees with the truth (FAIL for faulty).
    faulty_passed, reusable_failed : int
        The two errors outside the band: a faulty valve passed, a reusable valve failed.
    faulty, reusable : int
        The valves judged that the truth calls faulty and reusable.
    """

    marginal: int
    marginal_fraction: float
    accuracy_outside_band: float
    faulty_passed: int
    reusable_failed: int
    faulty: int
    reusable: int


@dataclass(frozen=True)
class JudgedCounts(VerdictCounts):
    """:class:`VerdictCounts` of the tests judged, and how many tests were INVALID instead (not judged)."""

    invalid: int
    judged: int


@dataclass(frozen=True)
class Evaluation(JudgedCounts):
    """A classifier on labelled data (:func:`evaluate`): the counts, over ``tests`` tests, judged by ``models``."""

    tests: int
    #: the names of the models that judged
    models: list[str]


def evaluate(classifier: ValveClassifier | None, dataset: Dataset) -> Evaluation:
    """Verdicts on a dataset against its physical labels.

    Tests that did not converge are INVALID and not judged (counted apart). Judged by ``classifier``, or (None)
    each variant's valves by the model that judges that variant's (the dataset's ``variants`` and
    ``variant_index``); ``models`` names the models that judged.
    """
    ok = dataset.columns.converged.astype(bool)
    if classifier is not None:
        judges = {0: classifier}
        which = np.zeros(len(dataset), dtype=int)
    else:
        judges = {n: judge_of(load_variant(name), None) for n, name in enumerate(dataset.provenance["variants"])}
        which = dataset.columns.variant_index.astype(int)
    verdicts = np.full(len(dataset), "", dtype=object)
    for n, judge in judges.items():
        rows = ok & (which == n)
        if rows.any():
            verdicts[rows] = judge.classify_many(dataset.features[rows])[0]
    counts = verdict_counts(verdicts[ok], dataset.labels[ok] == 1)
    return Evaluation(**vars(counts), invalid=int((~ok).sum()), judged=int(ok.sum()), tests=len(dataset),
                      models=sorted({judge.name for judge in judges.values()}))


def verdict_counts(verdicts: np.ndarray, truth: np.ndarray) -> VerdictCounts:
    """Verdicts against the truth (True: faulty): MARGINAL share, accuracy outside the band, and the errors."""
    decided = verdicts != Verdict.MARGINAL
    fail = verdicts == Verdict.FAIL
    return VerdictCounts(
        marginal=int((~decided).sum()),
        marginal_fraction=float((~decided).mean()) if len(truth) else float("nan"),
        accuracy_outside_band=float(((fail == truth) & decided).sum() / max(decided.sum(), 1)),
        faulty_passed=int((~fail & truth & decided).sum()),
        reusable_failed=int((fail & ~truth & decided).sum()),
        faulty=int(truth.sum()),
        reusable=int((~truth).sum()),
    )


def judged_counts(verdicts: np.ndarray, truth: np.ndarray, judged: np.ndarray) -> JudgedCounts:
    """:func:`verdict_counts` of the tests ``judged`` (their verdicts and truths given), and how many were not."""
    return JudgedCounts(**vars(verdict_counts(verdicts, truth)), invalid=int((~judged).sum()),
                        judged=int(judged.sum()))


__all__ = ["Evaluation", "JudgedCounts", "VerdictCounts", "evaluate", "judged_counts", "verdict_counts"]
