"""The package's own files are read-only to the program (#52): `edc-bench train` in every form leaves every file of the
installed package as it was, and the tests recorded before it still replay.

Measured before: `train --count 20` wrote its 40-test models over the shipped ones inside the package, the station
judged with them, every earlier record failed replay (exit 13) and `train --adopt shipped` could not undo it. The
forms run here in process on a small dataset (no simulation), except `train --count 20` itself (slow).
"""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest
from package_files import package_digest

from edc_bench.cli import main
from edc_bench.learning.dataset import COLUMNS, Dataset, DatasetColumns
from edc_bench.paths import package_folders, source_checkout
from edc_bench.verdict.classifier import (
    DEFAULT_MODEL,
    LINEAR_MODEL,
    ValveClassifier,
    file_sha256,
    packaged_model_path,
    variant_model_path,
)

pytest.importorskip("sklearn", reason="training needs the 'train' extra")


def _dataset(rows: int = 300, seed: int = 3) -> Dataset:
    """Features spread like a simulated population's, labelled by a physical-looking rule: no simulation."""
    rng = np.random.default_rng(seed)
    af_rel, a1_rel = rng.uniform(0.8, 2.4, rows), rng.uniform(0.8, 2.6, rows)
    columns = {name: rng.uniform(0.0, 1.0, rows) for name in COLUMNS}
    columns.update(af=af_rel * 0.07, a1=a1_rel * 0.0038, af_rel=af_rel, a1_rel=a1_rel,
                   faulty=(0.6 * af_rel + 0.4 * a1_rel > 1.6).astype(float), converged=np.ones(rows),
                   variant_index=np.zeros(rows), seed=np.arange(rows, dtype=float))
    return Dataset(DatasetColumns(**columns), {"synthetic": True})


def _labelled_history(url: str, count: int = 40) -> None:
    """A shop's history with ``count`` judged tests and their teardowns (enough for ``train --from-history``), as
    tests/history/test_shop_labels.py fills one."""
    from edc_bench.history.store import COLUMNS as ROW_COLUMNS
    from edc_bench.history.store import HistoryStore

    rng = np.random.default_rng(5)
    with HistoryStore(url) as store:
        for n in range(count):
            af_rel, a1_rel = rng.uniform(0.8, 1.8, 2)
            day, valve = f"2026-03-{1 + n % 28:02d}", f"S{n:03d}"
            row = {name: "" for name in ROW_COLUMNS if name not in ("id", "record_sha256", "indexed_at",
                                                                     "indexed_by")}
            row.update({name: None for name in ("af_v", "a1_v_s_per_mm", "probability_faulty", "distance",
                                                "model_name", "model_sha256", "coil_r20_ohm", "coil_in_spec",
                                                "model_fits", "stop_reason", "test_s", "simulated")})
            row.update(record_dir=f"/records/{valve}-{n}", started_at=f"{day}T08:00:00+00:00", valve_id=valve,
                       verdict="PASS", af_rel=af_rel, a1_rel=a1_rel)
            store.add_row(row)
            store.add_teardown(valve, "worn" if af_rel + a1_rel > 2.4 else "reusable", labelled_by="test",
                               labelled_at=f"{day}T12:00:00")


@pytest.fixture()
def station(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """A fresh station (its data folder: models, history) that has adopted nothing."""
    monkeypatch.setenv("EDC_BENCH_DATA_DIR", str(tmp_path / "station"))
    monkeypatch.delenv("EDC_BENCH_HISTORY_URL", raising=False)
    return tmp_path / "station"


@pytest.fixture(scope="module")
def dataset(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("dataset") / "small.npz"
    _dataset().save(path)
    return path


@pytest.fixture(scope="module")
def earlier_records(tmp_path_factory: pytest.TempPathFactory) -> list[Path]:
    """Tests recorded before any training: judged by the shipped network and by p-edc-hard's shipped own one."""
    from edc_bench.bench import run_simulated_test
    from edc_bench.config import load_variant
    from edc_bench.records.record import write_record

    out = tmp_path_factory.mktemp("records")
    folders = []
    for variant, valve, seed, model in (("p-edc-default", "worn", 5, DEFAULT_MODEL),
                                        ("p-edc-hard", "new", 1, "valve_mlp-p-edc-hard.onnx")):
        result = run_simulated_test(load_variant(variant), valve, seed)
        assert result.classification.model_sha256 == file_sha256(packaged_model_path(model))
        folders.append(write_record(result, out, figure=False))
    return folders


def _train(*args: object, code: int = 0) -> None:
    """``edc-bench train ARGS`` in process, asserting its exit code."""
    try:
        got = main(["train", *map(str, args)])
    except SystemExit as exc:  # argparse
        got = exc.code
    assert got == code, args


def _replays(folders: list[Path]) -> None:
    from edc_bench.replay import replay_record

    for folder in folders:
        report = replay_record(folder)
        assert report.reproduced, (folder.name, report.differences)


@pytest.mark.slow  # seconds: CI's slow pass runs it (the default suite stays under 5 minutes on CI)
def test_every_form_of_train_leaves_the_installed_package_as_it_was_and_earlier_records_replay(
        station: Path, dataset: Path, earlier_records: list[Path], tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    before = package_digest()
    assert any(path.endswith(DEFAULT_MODEL) for path in before)  # it sees the package's models
    shipped = {name: file_sha256(packaged_model_path(name)) for name in (DEFAULT_MODEL, LINEAR_MODEL)}
    url = f"sqlite:///{tmp_path / 'shop.sqlite'}"
    _labelled_history(url)
    inside = packaged_model_path().parent
    forms: list[tuple[tuple[object, ...], int]] = [
        (("--dataset", dataset), 0),  # the pair, as candidates
        (("--dataset", dataset, "--own", "--variants", "p-edc-hard"), 0),  # a shipped own network: a candidate
        (("--dataset", dataset, "--own", "--variants", "p-edc-hard", "--models-dir", station / "models"), 0),
        (("--dataset", dataset, "--models-dir", tmp_path / "elsewhere"), 0),
        (("--dataset", dataset, "--models-dir", inside), 2),  # the package's own folder: refused
        (("--dataset", dataset, "--models-dir", inside.parent / "new-folder"), 2),
        (("--dataset", dataset, "--save-dataset", inside / "data.npz"), 2),
        (("--from-history", "--db", url, "--prior-weight", 0, "--name", "shop-test"), 0),
        (("--adopt", station / "models" / "candidates" / "shop-test.onnx"), 0),
        (("--adopt", "shipped"), 0),
    ]
    if source_checkout() is None:  # from a source checkout it is the one form that writes the shipped models
        forms.append((("--rebuild-shipped", "--dataset", dataset), 2))
    for args, code in forms:
        _train(*args, code=code)
        assert package_digest() == before, args
    capsys.readouterr()
    assert not (inside.parent / "new-folder").exists()
    # --adopt shipped went back to the shipped models, p-edc-hard's own included (the station's stand-in set aside)
    assert ValveClassifier().path == packaged_model_path() and ValveClassifier().sha256 == shipped[DEFAULT_MODEL]
    from edc_bench.config import load_variant

    assert variant_model_path(load_variant("p-edc-hard")) == packaged_model_path("valve_mlp-p-edc-hard.onnx")
    assert sorted(p.name for p in (station / "models" / "candidates").iterdir()) == sorted(
        [f"{Path(n).stem}-sim-{_dataset().content_hash()[:8]}.onnx" for n in (DEFAULT_MODEL, LINEAR_MODEL,
                                                                               "valve_mlp-p-edc-hard.onnx")]
        + ["shop-test.onnx"])
    _replays(earlier_records)


def test_a_station_variant_s_own_network_trained_again_keeps_the_one_that_judged_earlier_tests(
        station: Path, dataset: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A variant of the station's own whose file names a network the package does not ship: `train --own` writes it
    where the variant finds it (the station's models folder), and the network it replaces is kept by its hash."""
    from edc_bench.bench import run_simulated_test
    from edc_bench.config import load_variant
    from edc_bench.config.loader import variant_file
    from edc_bench.records.record import write_record

    before = package_digest()
    own = "valve_mlp-shop-hard.onnx"
    text = variant_file("p-edc-hard").read_text(encoding="utf-8")
    assert 'model = "valve_mlp-p-edc-hard.onnx"' in text
    variant_path = tmp_path / "shop-hard.toml"
    variant_path.write_text(text.replace('model = "valve_mlp-p-edc-hard.onnx"', f'model = "{own}"'), encoding="utf-8")
    _train("--dataset", dataset, "--own", "--variants", variant_path)
    first = station / "models" / own
    assert first.is_file() and variant_model_path(load_variant(str(variant_path))) == first
    result = run_simulated_test(load_variant(str(variant_path)), "new", 1)
    assert result.classification.model_sha256 == file_sha256(first)
    folder = write_record(result, tmp_path / "records", figure=False)
    judged_by = file_sha256(first)
    _train("--dataset", dataset, "--own", "--variants", variant_path, "--seed", 7)  # another network, same name
    out = capsys.readouterr().out
    assert file_sha256(first) != judged_by
    kept = station / "models" / f"{first.stem}-{judged_by[:8]}.onnx"
    assert file_sha256(kept) == judged_by and f"kept the earlier {own} as {kept.name}" in out
    _replays([folder])
    # and the station's stand-in goes on judging: it is not a shipped model, so --adopt shipped leaves it
    _train("--adopt", "shipped")
    assert variant_model_path(load_variant(str(variant_path))) == first
    assert package_digest() == before


def test_rebuild_shipped_writes_the_source_tree_s_models_and_is_refused_in_an_installed_package(
        station: Path, dataset: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    import edc_bench.paths

    checkout = tmp_path / "checkout"
    (checkout / "edc_bench" / "verdict" / "models").mkdir(parents=True)
    monkeypatch.setattr(edc_bench.paths, "source_checkout", lambda: checkout)
    _train("--rebuild-shipped", "--dataset", dataset)
    assert sorted(p.name for p in (checkout / "edc_bench" / "verdict" / "models").iterdir()) == \
        [LINEAR_MODEL, DEFAULT_MODEL]
    assert not (station / "models").exists()
    _train("--rebuild-shipped", "--dataset", dataset, "--models-dir", tmp_path / "x", code=2)
    monkeypatch.setattr(edc_bench.paths, "source_checkout", lambda: None)
    capsys.readouterr()
    _train("--rebuild-shipped", "--dataset", dataset, code=2)
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "source checkout" in err and "--models-dir" in err, err


def test_a_source_checkout_is_told_from_an_installed_package(tmp_path: Path) -> None:
    root = source_checkout()
    folder = package_folders()[0]
    if root is None:
        assert "site-packages" in folder.parts or not (folder.parent / "pyproject.toml").is_file()
    else:
        assert folder == root / "edc_bench" and (root / "pyproject.toml").is_file()


@pytest.mark.slow
def test_train_as_a_new_user_runs_it_leaves_the_package_as_it_was(station: Path, earlier_records: list[Path],
                                                                   capsys: pytest.CaptureFixture[str]) -> None:
    """`edc-bench train --count 20`, the measured case, simulating its population."""
    before = package_digest()
    _train("--count", 20)
    out = capsys.readouterr().out
    assert "not adopted" in out and "edc-bench train --adopt" in out
    assert package_digest() == before
    assert ValveClassifier().path == packaged_model_path()
    _replays(earlier_records)
    shutil.rmtree(station / "models")
