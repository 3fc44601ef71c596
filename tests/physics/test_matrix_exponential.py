"""The plant's matrix exponential without SciPy: scipy.linalg.expm's figures."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg

from edc_bench.config import load_variant
from edc_bench.physics.matrix_exponential import expm
from edc_bench.physics.valve import nominal_plant


@pytest.mark.parametrize("name", ["p-edc-default", "p-edc-hard", "p-edc-long"])
def test_the_plants_discretisation_is_scipys(name: str) -> None:
    a, b = nominal_plant(load_variant(name)).state_matrices()
    aug = np.zeros((5, 5))
    aug[:3, :3], aug[:3, 3:] = a, b
    for dt_s in (1e-4, 1e-3, 5e-3, 0.02):  # a quantum, a tick, the longest step, and one that needs squarings
        want = scipy.linalg.expm(aug * dt_s)
        assert np.abs(expm(aug * dt_s) - want).max() <= 1e-13 * np.abs(want).max(), dt_s


def test_every_pade_degree_and_the_squarings_agree_with_scipy() -> None:
    rng = np.random.default_rng(7)
    for norm in (1e-3, 0.1, 0.5, 1.5, 4.0, 40.0):  # degrees 3, 5, 7, 9, 13, and 13 after squarings
        for n in (1, 2, 5):
            m = rng.normal(size=(n, n))
            m *= norm / np.abs(m).sum(axis=0).max()
            want = scipy.linalg.expm(m)
            assert np.abs(expm(m) - want).max() <= 1e-12 * np.abs(want).max(), (norm, n)


def test_a_stack_is_each_matrix_on_its_own() -> None:
    """The batch path exponentiates hundreds of valves' matrices at once: each must be what it is alone, whatever
    degree and squarings its norm calls for (a stack mixing them all)."""
    rng = np.random.default_rng(11)
    norms = np.array([1e-3, 0.1, 0.5, 1.5, 4.0, 40.0, 0.2, 40.0])
    stack = rng.normal(size=(len(norms), 5, 5))
    stack *= (norms / np.abs(stack).sum(axis=-2).max(axis=-1))[:, None, None]
    together = expm(stack.reshape(2, 4, 5, 5)).reshape(stack.shape)
    for m, got in zip(stack, together):
        want = scipy.linalg.expm(m)
        assert np.abs(got - want).max() <= 1e-12 * np.abs(want).max()
        assert np.abs(got - expm(m)).max() <= 1e-14 * np.abs(want).max()
