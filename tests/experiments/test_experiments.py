"""The issue's acceptance figures: a held-out population, the boundary trade-off, the paper's experiment.

All slow (population runs and the paper's experiment): `pytest -m slow`.
"""

from __future__ import annotations

from functools import cache
from pathlib import Path

import numpy as np
import pytest
from helpers import edc_bench

from edc_bench.experiments.studies import boundary_tradeoff, paper_experiment
from edc_bench.learning.dataset import Dataset, make_dataset
from edc_bench.learning.evaluation import evaluate
from edc_bench.verdict.classifier import LINEAR_MODEL, ValveClassifier, packaged_model_path

pytestmark = pytest.mark.slow


@cache
def held_out() -> Dataset:
    return make_dataset(["p-edc-default", "p-edc-long"], 250, 777)


def test_held_out_population_accuracy_and_marginal_share() -> None:
    """500 valves, a seed not used in training: >= 98 % right outside the band, <= 5 % MARGINAL."""
    data = held_out()
    assert len(data) == 500
    report = evaluate(ValveClassifier(), data)
    print(report)
    assert report.judged >= 490
    assert report.accuracy_outside_band >= 0.98
    assert report.marginal_fraction <= 0.05
    linear = evaluate(ValveClassifier(packaged_model_path(LINEAR_MODEL)), data)
    print("linear", linear)
    assert linear.accuracy_outside_band >= 0.98  # the paper's conclusion: a line suffices


def test_the_hard_pump_s_own_network_judges_its_valves_where_the_shipped_one_fails_reusable_ones() -> None:
    """#37: p-edc-hard's valve damping is 4/5 of its a1 (3/5 on the default pump), so wear crosses the limit along
    another line in (af/af0, a1/a1_0). 500 held-out valves (a seed not used in training): its own network, the one
    its variant file names, is >= 98 % right outside the band with <= 5 % MARGINAL; the shipped network, drawn on
    the default and long pumps, fails reusable valves."""
    data = make_dataset(["p-edc-hard"], 500, 777)
    own = evaluate(None, data)
    shipped = evaluate(ValveClassifier(packaged_model_path()), data)
    print("own", own, "shipped", shipped)
    assert own.models == ["valve_mlp-p-edc-hard"]
    assert own.judged >= 490
    assert own.accuracy_outside_band >= 0.98 and own.marginal_fraction <= 0.05
    assert shipped.reusable_failed > own.reusable_failed + 3


def test_boundary_tradeoff_is_monotonic() -> None:
    curve = boundary_tradeoff(ValveClassifier(), held_out())
    assert np.all(np.diff(curve.needless_replacement) <= 0)
    assert np.all(np.diff(curve.faulty_passed) >= 0)
    assert curve.needless_replacement[0] > 0.1 and curve.faulty_passed[-1] > 0.1


def test_paper_protocol_does_at_least_as_well_as_the_paper() -> None:
    exp = paper_experiment("p-edc-default", 2010)
    assert int((~exp.test_truth).sum()) == 10 and int(exp.test_truth.sum()) == 8
    print(f"{exp.reusable_right}/10 reusable, {exp.faulty_right}/8 faulty right (paper: 10/10, 7/8)")
    assert exp.reusable_right + exp.faulty_right >= 17


def test_paper_command_draws_figure_7(tmp_path: Path) -> None:
    proc = edc_bench("paper", "--figure", "fig7.png", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert "17 / 18" in proc.stdout  # the paper's column
    assert (tmp_path / "fig7.png").read_bytes()[:4] == b"\x89PNG"
