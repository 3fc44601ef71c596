"""Where edc-bench keeps files of its own: the station's data and its caches.

The user's platform directories (via platformdirs), unless the environment
says otherwise: ``EDC_BENCH_DATA_DIR`` and ``EDC_BENCH_CACHE_DIR`` (tests
and shared stations set them).
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any


def data_dir(create: bool = True) -> Path:
    """The station's data folder (history database, the station's variants); created if missing unless told not to."""
    configured = os.environ.get("EDC_BENCH_DATA_DIR")
    if configured:
        path = Path(configured)
    else:
        from platformdirs import user_data_dir

        path = Path(user_data_dir("edc-bench", appauthor=False))
    if create:
        path.mkdir(parents=True, exist_ok=True)
    return path


def cache_dir() -> Path:
    """The cache folder (results that can always be computed again); not created here."""
    configured = os.environ.get("EDC_BENCH_CACHE_DIR")
    if configured:
        return Path(configured)
    from platformdirs import user_cache_dir

    return Path(user_cache_dir("edc-bench", appauthor=False))


def write_json_atomic(path: Path, data: Any) -> None:
    """Write ``data`` as JSON to ``path`` atomically, creating its folder."""
    from edc_bench.records.writer import atomic_write

    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_write(path, lambda f: json.dump(data, f), mode="w")
