"""A pump type can be judged by its own network (#37): one boundary in (af/af0, a1/a1_0) does not serve pumps whose
resisting force splits between friction and damping differently. The variant file names the model; the shipped
network still judges every other variant, and a station's adopted model too."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from edc_bench.config import load_variant, parse_variant
from edc_bench.errors import ConfigError
from edc_bench.learning.evaluation import evaluate, verdict_counts
from edc_bench.verdict.classifier import (
    DEFAULT_MODEL,
    default_classifier,
    own_model_file,
    packaged_model_path,
    station_model_path,
    variant_model_path,
)


def test_the_hard_pump_is_judged_by_its_own_network_and_the_others_by_the_station_s() -> None:
    hard = load_variant("p-edc-hard")
    assert hard.diagnosis.model == own_model_file("p-edc-hard")
    assert variant_model_path(hard) == packaged_model_path(own_model_file("p-edc-hard"))
    for name in ("p-edc-default", "p-edc-long", "paper"):
        assert variant_model_path(load_variant(name)) == station_model_path()
    assert default_classifier(variant=hard).name == "valve_mlp-p-edc-hard"
    assert default_classifier(variant=load_variant("p-edc-default")).name == "valve_mlp"


def _with_model(name: str | None):
    data = load_variant("p-edc-hard").model_dump()
    data["diagnosis"]["model"] = name
    return data


def test_a_variant_naming_a_model_that_is_nowhere_is_told_how_to_build_it() -> None:
    variant = parse_variant(_with_model("valve_mlp-nowhere.onnx"))
    with pytest.raises(ConfigError, match=r"valve_mlp-nowhere\.onnx, which is in neither .*'edc-bench train "
                                          r"--variants \S*p-edc-hard(\.toml)? --own"):
        variant_model_path(variant)


@pytest.mark.parametrize("bad", ["../valve.onnx", "valve", "/tmp/x.onnx", ""])
def test_a_model_line_that_is_not_a_file_name_is_refused_when_the_variant_is_read(bad: str) -> None:
    with pytest.raises(ConfigError, match="model"):
        parse_variant(_with_model(bad))


def test_the_station_s_models_folder_comes_first(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("EDC_BENCH_DATA_DIR", str(tmp_path))
    (tmp_path / "models").mkdir()
    own = tmp_path / "models" / "valve_mlp-p-edc-hard.onnx"
    shutil.copyfile(packaged_model_path(DEFAULT_MODEL), own)
    assert variant_model_path(load_variant("p-edc-hard")) == own


def test_a_study_without_model_judges_each_variant_s_valves_by_its_own() -> None:
    """evaluate() over a dataset of two variants: each variant's rows by that variant's model."""
    from edc_bench.learning.dataset import COLUMNS, Dataset, DatasetColumns

    rows = 40
    rng = np.random.default_rng(3)
    features = rng.uniform(0.9, 2.2, size=(rows, 2))
    columns = {name: np.zeros(rows) for name in COLUMNS}
    index = np.repeat([0, 1], rows // 2)
    columns.update(af_rel=features[:, 0], a1_rel=features[:, 1], converged=np.ones(rows), variant_index=index,
                   faulty=(features.sum(axis=1) > 3.2).astype(float))
    dataset = Dataset(DatasetColumns(**columns), {"variants": ["p-edc-default", "p-edc-hard"]})
    report = evaluate(None, dataset)
    assert report.models == ["valve_mlp", "valve_mlp-p-edc-hard"]
    default, hard = (default_classifier(variant=load_variant(n)) for n in ("p-edc-default", "p-edc-hard"))
    expected = np.concatenate([default.classify_many(features[index == 0])[0],
                               hard.classify_many(features[index == 1])[0]])
    counts = verdict_counts(expected, dataset.labels == 1)
    assert {k: v for k, v in vars(report).items() if k in vars(counts)} == vars(counts)
    assert (default.classify_many(features)[0] != hard.classify_many(features)[0]).any()  # two boundaries
    shipped = evaluate(default, dataset)
    assert shipped.models == ["valve_mlp"]


@pytest.mark.parametrize("args, message", [
    (["--own"], "give one --variants NAME"),
    (["--own", "--variants", "p-edc-default", "p-edc-hard"], "give one --variants NAME"),
    (["--own", "--adopt", "shipped"], "give one of them"),
])
def test_train_own_refuses_what_it_cannot_do(args: list[str], message: str, tmp_path: Path) -> None:
    proc = subprocess.run([sys.executable, "-m", "edc_bench", "train", *args, "--models-dir", str(tmp_path)],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2, proc.stderr
    assert message in proc.stderr and "Traceback" not in proc.stderr


def test_a_hard_pump_s_test_records_the_model_that_judged_it(tmp_path: Path) -> None:
    proc = subprocess.run([sys.executable, "-m", "edc_bench", "classify", "--variant", "p-edc-hard", "--af", "0.08",
                           "--a1", "0.004", "--json"], capture_output=True, text=True, timeout=120, cwd=tmp_path)
    assert proc.returncode in (0, 10, 11, 12), proc.stderr
    out = json.loads(proc.stdout)
    assert out["model_name"] == "valve_mlp-p-edc-hard"


def test_a_bench_test_of_the_hard_pump_is_stopped_and_judged_by_its_own_network() -> None:
    from edc_bench.bench import run_simulated_test
    from edc_bench.verdict import early_stop

    seen = []
    real_check = early_stop.EarlyStop.check

    def check(self, *args, **kwargs):
        seen.append(self.classifier.name)
        return real_check(self, *args, **kwargs)

    mp = pytest.MonkeyPatch()
    mp.setattr(early_stop.EarlyStop, "check", check)
    try:
        result = run_simulated_test(load_variant("p-edc-hard"), "new", 1)
    finally:
        mp.undo()
    assert set(seen) == {"valve_mlp-p-edc-hard"}  # the early stop
    assert result.judgement.classification.model_name == "valve_mlp-p-edc-hard"  # the verdict and its record
    assert result.judgement.classification.model_sha256 == default_classifier(
        variant=load_variant("p-edc-hard")).sha256



def test_a_test_of_a_variant_whose_own_model_is_missing_is_refused_before_it_runs(tmp_path: Path) -> None:
    text = (Path(__file__).parents[2] / "configs" / "p-edc-hard.toml").read_text(encoding="utf-8")
    variant_file = tmp_path / "hard-elsewhere.toml"
    variant_file.write_text(text.replace('model = "valve_mlp-p-edc-hard.onnx"', 'model = "valve_mlp-elsewhere.onnx"'),
                            encoding="utf-8")
    proc = subprocess.run([sys.executable, "-m", "edc_bench", "test", "--variant", str(variant_file),
                           "--nominal-baseline"], capture_output=True, text=True, timeout=120, cwd=tmp_path)
    assert proc.returncode == 2, proc.stderr
    assert "valve_mlp-elsewhere.onnx, which is in neither" in proc.stderr and "Traceback" not in proc.stderr
    assert not list(tmp_path.glob("records/*"))  # refused before the test, not after it
    assert f"edc-bench train --variants {variant_file} --own" in proc.stderr  # builds this file's, named as it says


def test_a_boundary_study_of_variants_judged_by_different_models_is_refused_before_it_simulates(
        tmp_path: Path) -> None:
    proc = subprocess.run([sys.executable, "-m", "edc_bench", "study-boundary", "--variants", "p-edc-default",
                           "p-edc-hard", "--figure", str(tmp_path / "b.png")], capture_output=True, text=True,
                          timeout=120, cwd=tmp_path)
    assert proc.returncode == 2, proc.stderr
    assert "judged by different models (valve_mlp-p-edc-hard.onnx, valve_mlp.onnx)" in proc.stderr


@pytest.mark.parametrize("given", ["p-edc-hard", "TEST-HARD-0001", "configs/p-edc-hard.toml"])
def test_train_own_writes_the_file_the_variant_names_however_the_variant_is_given(given: str) -> None:
    from edc_bench.cli.train_cmd import _own_file

    if given.endswith(".toml"):
        given = str(Path(__file__).parents[2] / given)
    assert _own_file(given) == "valve_mlp-p-edc-hard.onnx"
