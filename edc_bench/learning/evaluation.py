"""How a classifier does on labelled data: its verdicts against the truth."""

from __future__ import annotations

from typing import Any

import numpy as np

from edc_bench.learning.dataset import Dataset
from edc_bench.verdict.classifier import ValveClassifier
from edc_bench.verdict.verdicts import Verdict


def evaluate(classifier: ValveClassifier, dataset: Dataset) -> dict[str, Any]:
    """Verdicts on a dataset against its physical labels.

    Tests that did not converge are INVALID and not judged (counted apart).
    """
    ok = dataset.columns["converged"].astype(bool)
    verdicts, _, _ = classifier.classify_many(dataset.features[ok])
    return {"tests": len(dataset), "invalid": int((~ok).sum()), "judged": int(ok.sum()),
            **verdict_counts(verdicts, dataset.labels[ok] == 1)}


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
