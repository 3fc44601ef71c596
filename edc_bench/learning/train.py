"""Train the classifiers offline and export them to ONNX with their metadata.

Two models on the relative features (af/af0, a1/a1_0):

- ``mlp``: the paper's network: 2 inputs, one hidden layer of 8 tanh units,
  sigmoid output (scikit-learn ``MLPClassifier``), after a standard scaler;
- ``linear``: logistic regression, as the paper's conclusion suggests.

Both are exported with skl2onnx (opset and IR version set explicitly, so
onnxruntime accepts them) and carry their metadata in the model: feature
names and definition, scaler, decision threshold, marginal band, training
data hash, versions. Training is deterministic for a fixed seed, and so is
the export: ``edc-bench train`` rebuilds the shipped models byte for byte.

Needs the ``train`` extra (scikit-learn, skl2onnx, onnx).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from typing import Any

import numpy as np

from edc_bench.learning.dataset import Dataset

FEATURE_NAMES = ("af_rel", "a1_rel")
TARGET_OPSET = 17
IR_VERSION = 8
DEFAULT_THRESHOLD = 0.5
DEFAULT_MARGINAL_BAND = 0.03


@dataclass
class TrainedModel:
    """A fitted pipeline and its ONNX bytes."""

    kind: str
    pipeline: Any
    onnx_bytes: bytes
    train_accuracy: float


def _pipeline(kind: str, seed: int) -> Any:
    from sklearn.linear_model import LogisticRegression
    from sklearn.neural_network import MLPClassifier
    from sklearn.pipeline import Pipeline
    from sklearn.preprocessing import StandardScaler

    if kind == "mlp":
        # weight decay keeps P(faulty) graded rather than a 0/1 step on separable data
        clf = MLPClassifier(hidden_layer_sizes=(8,), activation="tanh", solver="lbfgs", alpha=1.0,
                            max_iter=5000, random_state=seed)
    elif kind == "linear":
        clf = LogisticRegression(C=10.0, max_iter=5000)
    else:
        raise ValueError(f"unknown model kind {kind!r}; expected mlp or linear")
    return Pipeline([("scale", StandardScaler()), ("classify", clf)])


#: Significant digits of the scaler's figures in the model's metadata: more than the float32 the graph holds them
#: in, fewer than another CPU's rounding of the same training data reaches (about 1e-13 relative).
STORED_SIGNIFICANT_DIGITS = 8


def _stored(values: Any) -> list[float]:
    """Figures as the metadata stores them (:data:`STORED_SIGNIFICANT_DIGITS`)."""
    return [float(f"{float(v):.{STORED_SIGNIFICANT_DIGITS}g}") for v in values]


def export_onnx(pipeline: Any, metadata: dict[str, str]) -> bytes:
    """Convert a fitted pipeline to ONNX bytes with ``metadata`` as model properties."""
    import onnx
    from skl2onnx import to_onnx

    sample = np.zeros((1, len(FEATURE_NAMES)), dtype=np.float32)
    clf = pipeline.steps[-1][1]
    model = to_onnx(pipeline, sample, options={id(clf): {"zipmap": False}}, target_opset=TARGET_OPSET)
    model.ir_version = IR_VERSION
    # skl2onnx collects the opset imports in a set: their order follows Python's per-process string
    # hashing. Sort them so the same model gives the same bytes in every process.
    imports = sorted((entry.domain, entry.version) for entry in model.opset_import)
    del model.opset_import[:]
    for domain, version in imports:
        entry = model.opset_import.add()
        entry.domain, entry.version = domain, version
    model.doc_string = "edc-bench valve classifier: P(faulty) from (af/af0, a1/a1_0)"
    del model.metadata_props[:]
    for key, value in sorted(metadata.items()):
        entry = model.metadata_props.add()
        entry.key, entry.value = key, value
    onnx.checker.check_model(model)
    return model.SerializeToString()


def train(dataset: Dataset, kind: str, seed: int, *, threshold: float = DEFAULT_THRESHOLD,
          marginal_band: float = DEFAULT_MARGINAL_BAND, only_converged: bool = True) -> TrainedModel:
    """Fit one model on a simulated dataset and export it.

    Parameters
    ----------
    dataset : Dataset
        Training data (relative features and physical labels).
    kind : str
        ``"mlp"`` or ``"linear"``.
    seed : int
        Seed of the network's initial weights.
    threshold : float
        P(faulty) at or above which a valve fails.
    marginal_band : float
        Half-width, in relative-feature units, of the band around the
        boundary inside which a valve is MARGINAL.
    only_converged : bool
        Train only on tests that converged (a model never learns from bad tests).
    """
    keep = dataset.columns.converged.astype(bool) if only_converged else np.ones(len(dataset), bool)
    provenance = {"edc_bench.training_data_sha256": dataset.content_hash(),
                  "edc_bench.training_data": json.dumps(dataset.provenance, sort_keys=True)}
    return fit_and_export(dataset.features[keep], dataset.labels[keep], kind, seed, threshold=threshold,
                          marginal_band=marginal_band, metadata=provenance)


def fit_and_export(features: np.ndarray, labels: np.ndarray, kind: str, seed: int, *,
                   threshold: float = DEFAULT_THRESHOLD, marginal_band: float = DEFAULT_MARGINAL_BAND,
                   sample_weight: np.ndarray | None = None, metadata: dict[str, str] | None = None) -> TrainedModel:
    """Fit a model on relative features and labels and export it to ONNX with edc-bench's metadata.

    ``metadata`` adds to (or overrides) the standard entries: where the data came from, the model's name.
    """
    import skl2onnx
    import sklearn

    X = np.asarray(features, dtype=np.float64)
    y = np.asarray(labels, dtype=int)
    pipeline = _pipeline(kind, seed)
    fit_params = {} if sample_weight is None else {"classify__sample_weight": np.asarray(sample_weight, float)}
    pipeline.fit(X, y, **fit_params)
    scaler = pipeline.steps[0][1]
    entries = {
        "edc_bench.model_kind": kind,
        "edc_bench.feature_names": json.dumps(FEATURE_NAMES),
        "edc_bench.feature_definition": "ratio of identified af and a1 to the pump variant's new-valve baseline",
        "edc_bench.scaler_mean": json.dumps(_stored(scaler.mean_)),
        "edc_bench.scaler_scale": json.dumps(_stored(scaler.scale_)),
        "edc_bench.threshold": repr(float(threshold)),
        "edc_bench.marginal_band_rel": repr(float(marginal_band)),
        "edc_bench.training_rows": str(len(y)),
        "edc_bench.seed": str(seed),
        "edc_bench.output": "probabilities[:, 1] = P(faulty)",
        "versions": json.dumps({"scikit-learn": sklearn.__version__, "skl2onnx": skl2onnx.__version__}),
        **(metadata or {}),
    }
    accuracy = float((pipeline.predict(X) == y).mean())
    return TrainedModel(kind, pipeline, export_onnx(pipeline, entries), accuracy)
