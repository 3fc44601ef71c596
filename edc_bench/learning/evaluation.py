"""How a classifier does on labelled data: its verdicts against the truth."""

from __future__ import annotations

from typing import Any

import numpy as np

from edc_bench.config import load_variant
from edc_bench.learning.dataset import Dataset
from edc_bench.verdict.classifier import ValveClassifier, judge_of
from edc_bench.verdict.verdicts import Verdict


def evaluate(classifier: ValveClassifier | None, dataset: Dataset) -> dict[str, Any]:
    """Verdicts on a dataset against its physical labels.

    Tests that did not converge are INVALID and not judged (counted apart). Judged by ``classifier``, or (None)
    each variant's valves by the model that judges that variant's (the dataset's ``variants`` and
    ``variant_index``); ``models`` names the models that judged.
    """
    ok = dataset.columns["converged"].astype(bool)
    if classifier is not None:
        judges = {0: classifier}
        which = np.zeros(len(dataset), dtype=int)
    else:
        judges = {n: judge_of(load_variant(name), None) for n, name in enumerate(dataset.provenance["variants"])}
        which = dataset.columns["variant_index"].astype(int)
    verdicts = np.full(len(dataset), "", dtype=object)
    for n, judge in judges.items():
        rows = ok & (which == n)
        if rows.any():
            verdicts[rows] = judge.classify_many(dataset.features[rows])[0]
    return {"tests": len(dataset), "invalid": int((~ok).sum()), "judged": int(ok.sum()),
            "models": sorted({judge.name for judge in judges.values()}),
            **verdict_counts(verdicts[ok], dataset.labels[ok] == 1)}


def verdict_counts(verdicts: np.ndarray, truth: np.ndarray) -> dict[str, Any]:
    """Verdicts against the truth (True: faulty): MARGINAL share, accuracy outside the band, and the errors."""
    decided = verdicts != Verdict.MARGINAL
    fail = verdicts == Verdict.FAIL
    return {
        "marginal": int((~decided).sum()),
        "marginal_fraction": float((~decided).mean()) if len(truth) else float("nan"),
        "accuracy_outside_band": float(((fail == truth) & decided).sum() / max(decided.sum(), 1)),
        "faulty_passed": int((~fail & truth & decided).sum()),
        "reusable_failed": int((fail & ~truth & decided).sum()),
        "faulty": int(truth.sum()),
        "reusable": int((~truth).sum()),
    }


__all__ = ["evaluate", "verdict_counts"]
