"""The session's tests: a station data folder of their own (the operator remembered there)."""

from __future__ import annotations

from pathlib import Path

import pytest


@pytest.fixture(autouse=True)
def _station_data(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("EDC_BENCH_DATA_DIR", str(tmp_path / "station-data"))
