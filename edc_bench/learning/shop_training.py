"""Learning from the shop's teardowns: a candidate classifier from labelled real tests, with the simulation as prior.

The shipped models learnt from simulated valves, labelled by the variant's
resisting-force limit. A shop that opens valves learns what its own scrap
limit looks like in (af/af0, a1/a1_0). Here the candidate is the same
network as the shipped one, fitted on

- every labelled real test, weight 1 each, and
- the simulated population as a prior: its rows together weigh as much as
  ``prior_weight`` real tests (50 by default), so a handful of labels
  cannot throw the boundary about, and a few hundred outweigh the
  simulation where the two disagree.

Whether the candidate is better is measured, not assumed: k-fold
cross-validation over the real labels (folds stratified by label and
grouped by valve, so no valve is in its own test fold). In each fold the
candidate is trained on the prior and the other folds' labels, and judges
the held-out fold exactly as the bench would (ONNX, threshold, marginal
band); the current model judges the same tests. The figures of both sit
side by side.
"""

from __future__ import annotations

import hashlib
import json
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from edc_bench.errors import ConfigError
from edc_bench.learning.candidate_evaluation import EVALUATION_KEY, CandidateEvaluation, Score
from edc_bench.learning.dataset import Dataset, DatasetColumns, update_digest
from edc_bench.learning.evaluation import verdict_counts
from edc_bench.learning.train import TrainedModel, fit_and_export
from edc_bench.verdict.classifier import ValveClassifier

#: Fewest labelled tests to train on, and fewest of each class (each cross-validation fold needs both).
MIN_LABELS = 30
MIN_PER_CLASS = 5
FOLDS = 5
DEFAULT_PRIOR_WEIGHT = 50.0


@dataclass(frozen=True)
class LabelledTests:
    """Real tests with their teardown labels.

    Attributes
    ----------
    features_rel : numpy.ndarray
        (N, 2) af/af0 and a1/a1_0 as the bench measured them.
    labels : numpy.ndarray
        (N,) 1: the teardown found the valve worn or faulty; 0: reusable.
    valves : numpy.ndarray
        (N,) valve ids (folds keep a valve's tests together).
    """

    features_rel: np.ndarray
    labels: np.ndarray
    valves: np.ndarray

    def __len__(self) -> int:
        return len(self.labels)

    def content_hash(self) -> str:
        """SHA-256 of the features and labels (which data a candidate learnt from), counted as
        :meth:`Dataset.content_hash` counts its values, so another machine's last bits do not rename it."""
        digest = hashlib.sha256()
        update_digest(digest, "features_rel", self.features_rel)
        update_digest(digest, "labels", self.labels)
        return digest.hexdigest()

    def as_dataset(self, provenance: dict[str, Any]) -> Dataset:
        """The labels as a :class:`Dataset` (for ``evaluate`` and ``study-boundary`` on real labels)."""
        columns = DatasetColumns.labelled(self.features_rel[:, 0].astype(float),
                                          self.features_rel[:, 1].astype(float), self.labels.astype(bool))
        return Dataset(columns, provenance)



def _training_data(metadata: dict[str, str]) -> dict[str, object]:
    """A model's training-data provenance (its ``edc_bench.training_data`` metadata, JSON), as a mapping; {} for a
    model without one or with one that is not a JSON object."""
    try:
        found = json.loads(metadata.get("edc_bench.training_data", "{}"))
    except ValueError:
        return {}
    return found if isinstance(found, dict) else {}

def check_enough(labels: np.ndarray, valves: np.ndarray | None = None) -> None:
    """Refuse, with the counts, when there are too few labels to train and cross-validate on.

    Each class needs :data:`MIN_PER_CLASS` different valves: the folds keep a valve's tests together, and every
    fold must train on both classes.
    """
    labels = np.asarray(labels, dtype=int)
    valves = np.arange(len(labels)) if valves is None else np.asarray(valves)
    n, worn = len(labels), int(labels.sum())
    reusable = n - worn
    worn_valves, reusable_valves = len(set(valves[labels == 1])), len(set(valves[labels == 0]))
    if n < MIN_LABELS or worn_valves < MIN_PER_CLASS or reusable_valves < MIN_PER_CLASS:
        raise ConfigError(
            f"{n} labelled test(s) in the history ({reusable} reusable from {reusable_valves} valve(s), {worn} worn or "
            f"faulty from {worn_valves} valve(s)): training needs at least {MIN_LABELS} labelled tests, and each "
            f"finding from at least {MIN_PER_CLASS} different valves, to train and cross-validate "
            f"({max(MIN_LABELS - n, 0)} more tests; {max(MIN_PER_CLASS - reusable_valves, 0)} more reusable and "
            f"{max(MIN_PER_CLASS - worn_valves, 0)} more worn or faulty valves). Record teardown findings with "
            "'edc-bench label'.")


def score(name: str, verdicts: np.ndarray, faulty_decision: np.ndarray, labels: np.ndarray,
          in_sample: bool = False) -> Score:
    """Compare verdicts (and the decisions at the threshold) with teardown labels."""
    truth = labels.astype(bool)
    counts = verdict_counts(verdicts, truth)
    return Score(model=name, tests=len(labels), accuracy=float(np.mean(faulty_decision == truth)),
                 marginal=counts.marginal, accuracy_outside_band=counts.accuracy_outside_band,
                 worn_passed=counts.faulty_passed, reusable_failed=counts.reusable_failed, in_sample=in_sample)


def judge(classifier: ValveClassifier, features_rel: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Verdicts and decisions at the threshold, as the bench would give them."""
    verdicts, p, _ = classifier.classify_many(features_rel)
    return verdicts, p >= classifier.threshold


@dataclass
class ShopTraining:
    """A candidate trained on the shop's labels, and the cross-validated comparison with the current model."""

    candidate: TrainedModel
    name: str
    candidate_cv: Score
    current: Score
    folds: int
    prior_weight: float
    prior_rows: int
    labels: int


def _prior_rows(prior: Dataset | None) -> tuple[np.ndarray, np.ndarray]:
    if prior is None:
        return np.zeros((0, 2)), np.zeros(0, int)
    keep = prior.columns.converged.astype(bool)
    return prior.features[keep], prior.labels[keep]


def _export(features: np.ndarray, labels: np.ndarray, weights: np.ndarray, seed: int,
            metadata: dict[str, str], current: ValveClassifier) -> TrainedModel:
    return fit_and_export(features, labels, current.kind if current.kind in ("mlp", "linear") else "mlp", seed,
                          threshold=current.threshold, marginal_band=current.marginal_band,
                          sample_weight=weights, metadata=metadata)


def _weights(n_prior: int, n_real: int, prior_weight: float) -> np.ndarray:
    prior = np.full(n_prior, prior_weight / n_prior if n_prior else 0.0)
    return np.concatenate([prior, np.ones(n_real)])


def train_from_labels(labelled: LabelledTests, prior: Dataset | None, current: ValveClassifier, *,
                      prior_weight: float = DEFAULT_PRIOR_WEIGHT, seed: int = 2026, name: str | None = None,
                      source: dict[str, Any] | None = None) -> ShopTraining:
    """Train a candidate on the shop's labelled tests and cross-validate it against the current model.

    Parameters
    ----------
    labelled : LabelledTests
        The real tests and their teardown labels.
    prior : Dataset or None
        The simulated population (None, or ``prior_weight`` 0: the labels alone).
    current : ValveClassifier
        The model the station judges with now; the candidate keeps its kind,
        threshold and marginal band.
    prior_weight : float
        How many real tests the whole simulated population weighs as.
    seed : int
        Seed of the folds and of the network's initial weights.
    name : str, optional
        The candidate's name (default ``shop-`` and 8 hex digits of a hash of the labels, prior weight and seed).
    source : dict, optional
        Where the labels came from (history URL...), stored in the model.

    Raises
    ------
    ConfigError
        With too few labels (:func:`check_enough`).
    """
    from sklearn.model_selection import StratifiedGroupKFold

    if not np.isfinite(prior_weight) or prior_weight < 0:
        raise ConfigError(f"prior weight {prior_weight}: give the number of real tests the simulation counts as "
                          "(0 or more)")
    check_enough(labelled.labels, labelled.valves)
    prior_x, prior_y = _prior_rows(prior if prior_weight > 0 else None)
    x, y = labelled.features_rel.astype(float), labelled.labels.astype(int)
    labels_sha = labelled.content_hash()
    recipe = hashlib.sha256(f"{labels_sha} {prior_weight!r} {seed} {len(prior_x)}".encode()).hexdigest()
    name = name or f"shop-{recipe[:8]}"  # another prior weight or seed: another name, no overwritten candidate
    folds = StratifiedGroupKFold(n_splits=FOLDS, shuffle=True, random_state=seed)
    cv_verdicts = np.empty(len(y), dtype=object)
    cv_decisions = np.zeros(len(y), bool)
    with tempfile.TemporaryDirectory() as scratch:
        for k, (train_idx, test_idx) in enumerate(folds.split(x, y, groups=labelled.valves)):
            fold_x, fold_y = np.vstack([prior_x, x[train_idx]]), np.concatenate([prior_y, y[train_idx]])
            model = _export(fold_x, fold_y, _weights(len(prior_x), len(train_idx), prior_weight), seed,
                            {"edc_bench.model_name": f"{name}-fold{k}"}, current)
            path = Path(scratch) / f"fold{k}.onnx"
            path.write_bytes(model.onnx_bytes)
            cv_verdicts[test_idx], cv_decisions[test_idx] = judge(ValveClassifier(path), x[test_idx])
    now_verdicts, now_decisions = judge(current, x)
    # a current model that learnt from shop labels (an adopted candidate) has likely seen these very tests
    learnt_from_labels = "labels_sha256" in _training_data(current.metadata)
    evaluation = CandidateEvaluation(
        folds=FOLDS, labels=len(y), worn_or_faulty=int(y.sum()),
        candidate=score(f"{name} (cross-validated)", cv_verdicts.astype(str), cv_decisions, y),
        replaced=score(current.name, now_verdicts, now_decisions, y, learnt_from_labels),
        replaced_sha256=current.sha256)
    metadata = {
        "edc_bench.model_name": name,
        "edc_bench.training_data_sha256": labels_sha,
        "edc_bench.training_data": json.dumps({
            "real_labels": len(y), "real_worn_or_faulty": int(y.sum()), "labels_sha256": labels_sha,
            "prior_rows": len(prior_x), "prior_weight_in_real_tests": prior_weight,
            "prior": None if prior is None or prior_weight == 0 else prior.provenance, **(source or {})},
            sort_keys=True),
        "edc_bench.cross_validated_accuracy": repr(float(np.mean(cv_decisions == y.astype(bool)))),
        "edc_bench.base_model_sha256": current.sha256,
        EVALUATION_KEY: evaluation.to_json(),
    }
    candidate = _export(np.vstack([prior_x, x]), np.concatenate([prior_y, y]),
                        _weights(len(prior_x), len(y), prior_weight), seed, metadata, current)
    return ShopTraining(candidate=candidate, name=name, candidate_cv=evaluation.candidate,
                        current=evaluation.replaced, folds=FOLDS, prior_weight=prior_weight,
                        prior_rows=len(prior_x), labels=len(y))
