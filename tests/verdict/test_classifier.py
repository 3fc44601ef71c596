"""The packaged classifier: its metadata, the paper's vectors, the distance to the boundary, the MARGINAL band."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from helpers import edc_bench

from edc_bench.verdict.classifier import (
    DEFAULT_MODEL,
    LINEAR_MODEL,
    ValveClassifier,
    packaged_model_path,
)
from edc_bench.verdict.verdicts import Verdict


@pytest.mark.parametrize("name", [DEFAULT_MODEL, LINEAR_MODEL])
def test_packaged_models_carry_their_metadata(name: str) -> None:
    clf = ValveClassifier(packaged_model_path(name))
    meta = clf.metadata
    assert json.loads(meta["edc_bench.feature_names"]) == ["af_rel", "a1_rel"]
    assert len(json.loads(meta["edc_bench.scaler_mean"])) == 2
    assert clf.threshold == 0.5 and clf.marginal_band == 0.03
    assert len(meta["edc_bench.training_data_sha256"]) == 64
    assert "scikit-learn" in json.loads(meta["versions"])
    assert json.loads(meta["edc_bench.training_data"])["variants"] == ["p-edc-default", "p-edc-long"]


@pytest.mark.parametrize(("af", "a1", "verdict"), [(0.0469, 0.0118, Verdict.PASS), (0.0715, 0.0239, Verdict.FAIL),
                                                   (0.1284, 0.0471, Verdict.FAIL)], ids=["V1", "V2", "V3"])
def test_paper_vectors_judged_like_the_paper(tmp_path: Path, af: float, a1: float, verdict: str) -> None:
    proc = edc_bench("classify", "--variant", "paper", "--af", str(af), "--a1", str(a1), "--json", cwd=tmp_path)
    assert proc.returncode == {Verdict.PASS: 0, Verdict.FAIL: 11}[verdict], proc.stderr
    out = json.loads(proc.stdout)
    assert out["verdict"] == verdict
    assert (out["distance"] > 0) == (verdict == Verdict.FAIL)


def test_distance_is_the_distance_to_the_boundary() -> None:
    clf = ValveClassifier()
    points = np.array([[1.0, 1.0], [1.3, 1.5], [1.5, 1.5], [2.0, 2.5]])
    faulty = clf.probabilities(points) >= clf.threshold
    d = clf.distances(points)
    assert np.array_equal(d > 0, faulty)
    angles = np.linspace(0, 2 * np.pi, 90, endpoint=False)
    ring = np.column_stack([np.cos(angles), np.sin(angles)])
    for point, dist, side in zip(points, np.abs(d), faulty, strict=True):
        inside = clf.probabilities(point + 0.9 * dist * ring) >= clf.threshold
        outside = clf.probabilities(point + 1.1 * dist * ring) >= clf.threshold
        assert (inside == side).all()  # nothing closer than the distance changes class
        assert (outside != side).any()  # and something just beyond it does


def test_marginal_band_around_the_boundary() -> None:
    clf = ValveClassifier()
    lo, hi = 1.0, 2.0  # bisect along the diagonal for a point on the boundary
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if clf.probabilities(np.array([[mid, mid]]))[0] >= clf.threshold else (mid, hi)
    on = 0.5 * (lo + hi)
    step = clf.marginal_band * 2.0  # along the diagonal, at least the band's width from the boundary
    verdicts, _, d = clf.classify_many(np.array([[on, on], [on - step, on - step], [on + step, on + step],
                                                 [1.0, 1.0], [2.0, 2.0]]))
    assert list(verdicts) == [Verdict.MARGINAL, Verdict.PASS, Verdict.FAIL, Verdict.PASS, Verdict.FAIL]
    assert abs(d[0]) < 0.005


@pytest.mark.parametrize("name", [DEFAULT_MODEL, LINEAR_MODEL])
def test_verdicts_alone_are_classify_many_s_verdicts(name: str) -> None:
    """The early stop's cheaper path skips the full boundary scan only where the band cannot be reached; the
    verdicts are the same everywhere, the band's edges included (points placed at band +/- a hair from the
    boundary along the scan's own directions, and a random cloud over the feature plane)."""
    clf = ValveClassifier(packaged_model_path(name))
    rng = np.random.default_rng(3)
    cloud = np.column_stack([rng.uniform(0.6, 2.2, 4000), rng.uniform(0.6, 2.8, 4000)])
    # points on the boundary (bisected along rays from (1, 1)), then moved off it by about the band
    angles = rng.uniform(0.0, 0.5 * np.pi, 200)
    rays = np.column_stack([np.cos(angles), np.sin(angles)])
    lo, hi = np.zeros(200), np.full(200, 3.0)
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        faulty = clf.probabilities(1.0 + mid[:, None] * rays) >= clf.threshold
        lo, hi = np.where(faulty, lo, mid), np.where(faulty, mid, hi)
    on = 1.0 + hi[:, None] * rays
    offsets = clf.marginal_band * np.array([0.5, 0.9, 0.99, 1.01, 1.1, 2.0])
    near = np.concatenate([on + s * o * rays for o in offsets for s in (-1.0, 1.0)])
    points = np.concatenate([cloud, on, near])
    full, _, _ = clf.classify_many(points)
    fast = clf.verdicts(points)
    assert list(fast) == list(full)
    assert {Verdict.PASS.value, Verdict.MARGINAL.value, Verdict.FAIL.value} <= set(full)
