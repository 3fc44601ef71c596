"""Dataset files keep their provenance and detect tampering."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from edc_bench.errors import ConfigError
from edc_bench.learning.dataset import Dataset, make_dataset


@pytest.mark.slow  # a population run (12 simulated tests), training's tooling
def test_dataset_file_keeps_provenance_and_detects_tampering(tmp_path: Path) -> None:
    data = make_dataset(["p-edc-default"], 12, 9, workers=1)
    path = tmp_path / "d.npz"
    data.save(path)
    back = Dataset.load(path)
    assert back.provenance["variants"] == ["p-edc-default"] and back.provenance["seed"] == 9
    assert back.provenance["generator_version"] == 1 and back.provenance["rows"] == 12
    assert back.content_hash() == data.content_hash()
    columns = dict(back.columns.items())
    columns["af"] = columns["af"] * 1.01
    np.savez(path, provenance=np.array(json.dumps(back.provenance)), **columns)
    with pytest.raises(ConfigError, match="does not match its recorded hash"):
        Dataset.load(path)
