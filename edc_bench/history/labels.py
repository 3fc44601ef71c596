"""The history's teardown labels as training and evaluation data."""

from __future__ import annotations

import numpy as np

from edc_bench.history.store import HistoryStore
from edc_bench.learning.shop_training import LabelledTests


def labelled_tests(store: HistoryStore, include_simulated: bool = False) -> LabelledTests:
    """Every teardown with a judged test before it: the test's relative features and the teardown's label (tests on
    the simulated rig left out unless ``include_simulated``)."""
    matches = store.labelled_tests(include_simulated)
    tests = [match.test for match in matches if match.test is not None]  # every labelled test has one
    return LabelledTests(
        features_rel=np.array([[t.af_rel, t.a1_rel] for t in tests], dtype=float).reshape(-1, 2),
        labels=np.array([match.label for match in matches], dtype=int),
        valves=np.array([match.teardown.valve_id for match in matches], dtype=object),
    )
