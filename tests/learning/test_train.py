"""`edc-bench train` rebuilds the shipped classifiers, byte for byte (slow: `pytest -m slow`)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from edc_bench.verdict.classifier import DEFAULT_MODEL, LINEAR_MODEL, packaged_model_path


@pytest.mark.slow
def test_train_rebuilds_the_shipped_models_byte_for_byte(tmp_path: Path) -> None:
    # another string-hash seed than the build's: nothing may depend on set or dict-of-str order
    env = {**os.environ, "PYTHONHASHSEED": "12345"}
    proc = subprocess.run([sys.executable, "-m", "edc_bench", "train", "--out-dir", str(tmp_path)],
                          capture_output=True, text=True, cwd=tmp_path, timeout=600, env=env)
    assert proc.returncode == 0, proc.stderr
    for name in (DEFAULT_MODEL, LINEAR_MODEL):
        assert (tmp_path / name).read_bytes() == packaged_model_path(name).read_bytes(), name
