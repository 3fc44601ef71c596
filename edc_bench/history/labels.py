"""The history's teardown labels as training and evaluation data."""

from __future__ import annotations

import numpy as np

from edc_bench.history.store import HistoryStore
from edc_bench.learning.shop_training import LabelledTests


def labelled_tests(store: HistoryStore, include_simulated: bool = False) -> LabelledTests:
    """Every teardown with a judged test before it: the test's relative features and the teardown's label (tests on
    the simulated rig left out unless ``include_simulated``)."""
    rows = store.labelled_tests(include_simulated)
    return LabelledTests(
        features_rel=np.array([[r["af_rel"], r["a1_rel"]] for r in rows], dtype=float).reshape(-1, 2),
        labels=np.array([r["label"] for r in rows], dtype=int),
        valves=np.array([r["valve_id"] for r in rows], dtype=object),
    )
