"""Shared fixtures."""

from __future__ import annotations

import pytest

from edc_bench.config import Variant, load_variant
from edc_bench.protocol import Icd, default_icd


@pytest.fixture(scope="session")
def icd() -> Icd:
    return default_icd()


@pytest.fixture(scope="session")
def variant() -> Variant:
    return load_variant("p-edc-default")


@pytest.fixture(scope="session", params=["p-edc-default", "p-edc-long"])
def any_variant(request: pytest.FixtureRequest) -> Variant:
    return load_variant(request.param)


@pytest.fixture(scope="session", autouse=True)
def _station_dirs(tmp_path_factory: pytest.TempPathFactory) -> None:
    """Keep the tests' history database and caches out of the user's own folders (subprocesses inherit it)."""
    import os

    base = tmp_path_factory.mktemp("station")
    os.environ.setdefault("EDC_BENCH_DATA_DIR", str(base / "data"))
    os.environ.setdefault("EDC_BENCH_CACHE_DIR", str(base / "cache"))
