"""A station adopts a classifier explicitly: copied into its models folder, named with its hash.

Nothing changes the model a station judges with but :func:`adopt`
(``edc-bench train --adopt``): a candidate trained from the shop's labels
waits as a file until someone who has read its cross-validated figures
adopts it. Every record names the model that judged it (name, file,
SHA-256), and replay finds it again by its hash.
"""

from __future__ import annotations

import datetime as dt
import re
import shutil
from pathlib import Path
from typing import Any

from edc_bench.errors import ConfigError
from edc_bench.paths import atomic_write, write_json_atomic
from edc_bench.verdict.classifier import (
    ADOPTED_FILE,
    ValveClassifier,
    file_sha256,
    packaged_model_path,
    station_models_dir,
)


def load_candidate(candidate: Path) -> ValveClassifier:
    """The model file ``candidate``, checked: it exists, loads and carries edc-bench's metadata (a ConfigError
    saying why not)."""
    candidate = Path(candidate)
    if not candidate.is_file():
        raise ConfigError(f"--adopt {candidate}: no such model file (give the .onnx 'train --from-history' wrote, "
                          "or 'shipped')")
    return ValveClassifier(candidate)  # refuses a file that is not an edc-bench model, saying why


def adopt(candidate: Path, adopted_by: str, model: ValveClassifier | None = None) -> dict[str, Any]:
    """Make ``candidate`` the station's model; returns the adoption written.

    The file is checked (:func:`load_candidate`, unless its ``model`` is given already loaded), copied into the
    station's models folder as ``NAME-SHA8.onnx`` and recorded with its SHA-256, who adopted it and when.
    """
    candidate = Path(candidate)
    model = model or load_candidate(candidate)
    folder = station_models_dir()
    try:
        folder.mkdir(parents=True, exist_ok=True)
        safe_name = re.sub(r"[^A-Za-z0-9._-]+", "_", model.name).strip("._") or "model"
        target = folder / f"{safe_name}-{model.sha256[:8]}.onnx"
        if not target.exists() or file_sha256(target) != model.sha256:  # absent, or changed since: the candidate's bytes
            atomic_write(target, lambda handle: handle.write(candidate.read_bytes()))
        adoption = {"file": target.name, "sha256": model.sha256, "name": model.name,
                    "adopted_at": dt.datetime.now(dt.UTC).isoformat(timespec="seconds"), "adopted_by": adopted_by,
                    "source": str(candidate.resolve())}
        write_json_atomic(folder / ADOPTED_FILE, adoption)
    except OSError as exc:
        raise ConfigError(f"cannot write the station's models folder {folder}: {exc.strerror}") from None
    return adoption


def adopt_shipped() -> Path:
    """Go back to the packaged network; the adopted file stays in the folder (old records name it)."""
    marker = station_models_dir() / ADOPTED_FILE
    if marker.exists():
        try:
            shutil.move(str(marker), str(marker.with_suffix(".json.previous")))
        except OSError as exc:
            raise ConfigError(f"cannot change {marker}: {exc.strerror}") from None
    return packaged_model_path()
