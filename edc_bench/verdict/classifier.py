"""The verdict: an ONNX model run with onnxruntime, one session per process.

Given a trustworthy test's af and a1 and the variant's baseline, the model
gives P(faulty). The signed distance to the decision boundary (in units of
the relative features, positive on the faulty side) is found geometrically:
rays in 24 directions are scanned for the nearest change of class, then the
closest bracket is refined; this holds for any model, also where its
probability saturates. Inside the model's marginal band the verdict is
MARGINAL (retest); outside it, FAIL if P(faulty) reaches the threshold, else
PASS.
"""

from __future__ import annotations

import hashlib
import json
import math
import shlex
from dataclasses import dataclass
from functools import lru_cache
from importlib import resources
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from edc_bench.errors import ConfigError
from edc_bench.verdict.verdicts import Verdict

if TYPE_CHECKING:
    from edc_bench.config.models import Variant

DEFAULT_MODEL = "valve_mlp.onnx"
LINEAR_MODEL = "valve_linear.onnx"
_DIRECTIONS = 24
_RADII = np.geomspace(1e-3, 3.0, 28)
_REFINE = 24


def packaged_model_path(name: str = DEFAULT_MODEL) -> Path:
    """Path of a model shipped inside the package."""
    return Path(str(resources.files("edc_bench.verdict").joinpath("models", name)))


#: In the station's models folder: which model the station adopted (absent: the packaged network).
ADOPTED_FILE = "adopted.json"


def station_models_dir() -> Path:
    """The station's own models (adopted candidates), in its data folder."""
    from edc_bench.paths import data_dir

    return data_dir(create=False) / "models"


def file_sha256(path: Path) -> str:
    """SHA-256 of a file's bytes (a model's identity)."""
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def adopted_model() -> dict[str, str] | None:
    """The station's adoption (``file``, ``sha256``, ``name``, ``adopted_at``, ``adopted_by``), or None.

    Raises
    ------
    ConfigError
        If the adopted model is missing or was changed after it was adopted.
    """
    marker = station_models_dir() / ADOPTED_FILE
    if not marker.exists():
        return None
    revert = "adopt it again with 'edc-bench train --adopt FILE', or go back with 'edc-bench train --adopt shipped'"
    try:
        adoption = json.loads(marker.read_text(encoding="utf-8"))
        path = station_models_dir() / adoption["file"]
        sha = adoption["sha256"]
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise ConfigError(f"{marker}: not a readable model adoption ({exc}); {revert}") from None
    if not path.is_file():
        raise ConfigError(f"the station's adopted model {path} is missing; {revert}")
    if file_sha256(path) != sha:
        raise ConfigError(f"the station's adopted model {path} changed after it was adopted; {revert}")
    return {**adoption, "path": str(path)}


def station_model_path() -> Path:
    """The model this station judges with: the adopted one, else the packaged network."""
    adoption = adopted_model()
    return Path(adoption["path"]) if adoption else packaged_model_path()


def own_model_file(variant_name: str) -> str:
    """The file name ``edc-bench train --variants NAME --own`` gives a variant's own network."""
    return f"valve_mlp-{variant_name}.onnx"


def shipped_model_path(variant: Variant) -> Path:
    """The packaged model ``variant``'s valves are judged by on a station that adopted and built none: its own, if
    its ``[diagnosis] model`` names one, else the shipped network (for figures that must not depend on a
    station)."""
    return packaged_model_path(variant.diagnosis.model or DEFAULT_MODEL)


def variant_model_path(variant: Variant) -> Path:
    """The model ``variant``'s valves are judged by: the one its ``[diagnosis] model`` names (in the station's
    models folder, else the package's), else the station's (:func:`station_model_path`).

    Raises
    ------
    ConfigError
        If the variant names a model that is in neither folder.
    """
    name = variant.diagnosis.model
    if name is None:
        return station_model_path()
    folders = (station_models_dir(), packaged_model_path().parent)
    for folder in folders:
        if (folder / name).is_file():
            return folder / name
    given = shlex.quote(variant.source_file or variant.name)  # the file itself: a name may find another
    raise ConfigError(f"variant {variant.name} is judged by its own classifier {name}, which is in neither "
                      f"{folders[0]} nor {folders[1]}: build it with 'edc-bench train --variants {given} "
                      f"--own --models-dir {folders[0]}', or delete the [diagnosis] model line to judge with the "
                      "station's model")


def shipped_model_hashes() -> set[str]:
    """The SHA-256 of each network the bench judges with unless a station adopts another: the shipped default
    and each shipped variant's own (``valve_mlp*.onnx``; the linear model is the paper's comparison, not a
    judge)."""
    folder = packaged_model_path().parent
    return {file_sha256(path) for path in sorted(folder.glob("valve_mlp*.onnx"))}


def find_model(sha256: str) -> Path | None:
    """A model file with this SHA-256 among the packaged models and the station's own, or None."""
    folders = [packaged_model_path().parent, station_models_dir()]
    for folder in folders:
        if folder.is_dir():
            for path in sorted(folder.glob("*.onnx")):
                if file_sha256(path) == sha256:
                    return path
    return None


def verdicts_of(probability_faulty: np.ndarray | float, distance: np.ndarray | float, threshold: float,
                marginal_band: float) -> np.ndarray:
    """The classifier's rule: MARGINAL within ``marginal_band`` of the boundary, else FAIL where P(faulty) reaches
    ``threshold``, else PASS.

    Parameters
    ----------
    probability_faulty, distance : float or numpy.ndarray
        P(faulty) and the signed distance to the boundary (+/-inf: beyond the scan) of each valve.
    threshold, marginal_band : float
        The model's.

    Returns
    -------
    numpy.ndarray
        The verdicts' names (``"PASS"``, ``"MARGINAL"``, ``"FAIL"``), one per valve.

    The one place the rule is written: :meth:`ValveClassifier.classify_many` judges with it, and
    :mod:`edc_bench.records.consistency` re-decides a record's classification with it from the figures kept.
    """
    faulty = np.asarray(probability_faulty) >= threshold
    return np.where(np.abs(np.asarray(distance, dtype=float)) < marginal_band, Verdict.MARGINAL.value,
                    np.where(faulty, Verdict.FAIL.value, Verdict.PASS.value))


@dataclass(frozen=True)
class Classification:
    """The model's judgement of one valve.

    Attributes
    ----------
    verdict : Verdict
        PASS, MARGINAL or FAIL.
    probability_faulty : float
        P(faulty) from the model.
    distance : float
        Signed distance to the boundary in relative-feature units
        (positive: faulty side).
    features_rel : tuple of float
        (af/af0, a1/a1_0) as given to the model.
    """

    verdict: Verdict
    probability_faulty: float
    distance: float
    features_rel: tuple[float, float]
    model: str


class ValveClassifier:
    """An onnxruntime session on a valve model and the rules around it.

    Parameters
    ----------
    path : pathlib.Path, optional
        ONNX model; by default the station's (:func:`station_model_path`: the
        adopted model, else the packaged network).
    """

    def __init__(self, path: Path | None = None) -> None:
        import onnxruntime as ort

        self.path = Path(path) if path is not None else station_model_path()
        if not self.path.is_file():
            raise ConfigError(f"classifier model {self.path} not found; build it with 'edc-bench train'")
        #: identity of the exact model file, recorded with every verdict it gives
        self.sha256 = file_sha256(self.path)
        options = ort.SessionOptions()
        options.intra_op_num_threads = 1
        try:
            self.session = ort.InferenceSession(str(self.path), options, providers=["CPUExecutionProvider"])
        except Exception as exc:  # noqa: BLE001 - onnxruntime raises its own untyped errors
            raise ConfigError(f"classifier model {self.path} cannot be loaded: {exc}") from None
        meta = self.session.get_modelmeta().custom_metadata_map
        self.metadata = dict(meta)
        try:
            self.threshold = float(meta["edc_bench.threshold"])
            self.marginal_band = float(meta["edc_bench.marginal_band_rel"])
            self.feature_names = tuple(json.loads(meta["edc_bench.feature_names"]))
        except (KeyError, ValueError) as exc:
            raise ConfigError(f"classifier model {self.path} lacks edc-bench metadata ({exc})") from None
        self.kind = meta.get("edc_bench.model_kind", "?")
        #: the model's name: given when it was trained (a shop's candidate), else its file's stem
        self.name = meta.get("edc_bench.model_name") or self.path.stem
        self._input = self.session.get_inputs()[0].name
        outputs = [o.name for o in self.session.get_outputs()]
        self._output = "probabilities" if "probabilities" in outputs else outputs[-1]
        angles = np.linspace(0.0, 2 * np.pi, _DIRECTIONS, endpoint=False)
        self._directions = np.column_stack([np.cos(angles), np.sin(angles)])

    def probabilities(self, features_rel: np.ndarray) -> np.ndarray:
        """P(faulty) for rows of relative features, (N, 2) -> (N,)."""
        x = np.ascontiguousarray(features_rel, dtype=np.float32)
        return self.session.run([self._output], {self._input: x})[0][:, 1]

    def _flipped(self, x: np.ndarray, faulty: np.ndarray, radii: np.ndarray) -> np.ndarray:
        """Whether the class at x + r u differs from x's, for every direction u and radius r: (n, directions,
        radii)."""
        pts = x[:, None, None, :] + radii[None, None, :, None] * self._directions[None, :, None, :]
        side = (self.probabilities(pts.reshape(-1, 2)) >= self.threshold).reshape(len(x), _DIRECTIONS, len(radii))
        return side != faulty[:, None, None]

    def distances(self, features_rel: np.ndarray, faulty: np.ndarray | None = None) -> np.ndarray:
        """Signed distance of each row to the boundary (positive: faulty side).

        Distances beyond the scanned 3.0 are reported as +/-inf.
        """
        x = np.asarray(features_rel, dtype=np.float64)
        n = len(x)
        if faulty is None:
            faulty = self.probabilities(x) >= self.threshold
        dirs = self._directions
        flipped = self._flipped(x, faulty, _RADII)  # stage 1
        any_flip = flipped.any(axis=2)
        first = np.where(any_flip, flipped.argmax(axis=2), len(_RADII))  # (n, dirs)
        best = first.min(axis=1)
        found = best < len(_RADII)
        # stage 2: refine inside the bracket [r_{k-1}, r_k] along every direction that first flips in it (several
        # directions often share the bracket, and the nearest boundary may lie along any of them)
        idx = np.minimum(best, len(_RADII) - 1)
        lo = np.where(idx > 0, _RADII[np.maximum(idx - 1, 0)], 0.0)
        hi = _RADII[idx]
        steps = np.linspace(0.0, 1.0, _REFINE + 1)[1:]
        radii = lo[:, None] + (hi - lo)[:, None] * steps[None, :]  # (n, refine)
        pts2 = x[:, None, None, :] + radii[:, None, :, None] * dirs[None, :, None, :]  # (n, dirs, refine, 2)
        side2 = (self.probabilities(pts2.reshape(-1, 2)) >= self.threshold).reshape(n, _DIRECTIONS, _REFINE)
        flip2 = (side2 != faulty[:, None, None]) & (first == best[:, None])[:, :, None]
        k2 = np.where(flip2.any(axis=2), flip2.argmax(axis=2), _REFINE)  # (n, dirs); _REFINE: no flip
        k2 = np.where(k2.min(axis=1) < _REFINE, k2.min(axis=1), _REFINE - 1)
        rows = np.arange(n)
        inner = np.where(k2 > 0, radii[rows, np.maximum(k2 - 1, 0)], lo)
        dist = 0.5 * (inner + radii[rows, k2])
        dist = np.where(found, dist, np.inf)
        return np.where(faulty, dist, -dist)

    def classify_many(self, features_rel: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Verdicts, P(faulty) and distances for rows of relative features."""
        p = self.probabilities(features_rel)
        d = self.distances(features_rel, p >= self.threshold)
        return verdicts_of(p, d, self.threshold, self.marginal_band), p, d

    def verdicts(self, features_rel: np.ndarray) -> np.ndarray:
        """The verdicts :meth:`classify_many` gives, for a fraction of its cost away from the boundary.

        A point whose class changes nowhere within the marginal band's radius (the scan's first stage, cut at the
        first radius that reaches the band) is outside the band whatever the refinement would find: the distance
        is at least the radius before the first change. Only the other points are scanned in full. For the early
        stop, which asks this once a period inside a real-time tick.
        """
        x = np.asarray(features_rel, dtype=np.float64)
        faulty = self.probabilities(x) >= self.threshold
        near = _RADII[: int(np.searchsorted(_RADII, self.marginal_band)) + 1]
        close = self._flipped(x, faulty, near).any(axis=(1, 2))
        out = np.where(faulty, Verdict.FAIL.value, Verdict.PASS.value).astype(object)
        if close.any():
            out[close] = self.classify_many(x[close])[0]
        return out

    def classify(self, af_rel: float, a1_rel: float) -> Classification:
        """Judge one valve from its relative features."""
        if not (math.isfinite(af_rel) and math.isfinite(a1_rel)):
            raise ConfigError(f"features must be finite numbers, got af_rel={af_rel}, a1_rel={a1_rel}")
        verdicts, p, d = self.classify_many(np.array([[af_rel, a1_rel]]))
        return Classification(Verdict(verdicts[0]), float(p[0]), float(d[0]), (float(af_rel), float(a1_rel)), self.kind)

    def boundary_grid(self, af_range: tuple[float, float], a1_range: tuple[float, float],
                      n: int = 200) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """P(faulty) on a grid of relative features, for plots."""
        af = np.linspace(*af_range, n)
        a1 = np.linspace(*a1_range, n)
        A, B = np.meshgrid(af, a1)
        p = self.probabilities(np.column_stack([A.ravel(), B.ravel()])).reshape(A.shape)
        return A, B, p


def default_classifier(path: str | None = None, variant: Variant | None = None) -> ValveClassifier:
    """One session per model per process (created on first use): ``path``, else the model ``variant``'s valves are
    judged by (:func:`variant_model_path`), else the station's model."""
    if path:
        return _session(str(Path(path).resolve()))
    return _session(str((variant_model_path(variant) if variant is not None else station_model_path()).resolve()))


def judge_of(variant: Variant, classifier: ValveClassifier | None) -> ValveClassifier:
    """``classifier`` where one is given (a study's ``--model``), else the model ``variant``'s valves are judged
    by."""
    return classifier if classifier is not None else default_classifier(variant=variant)


@lru_cache(maxsize=4)
def _session(path: str) -> ValveClassifier:
    return ValveClassifier(Path(path))
