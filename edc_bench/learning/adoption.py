"""A station adopts a classifier explicitly: copied into its models folder, named with its hash.

Nothing changes the model a station judges with but :func:`adopt`
(``edc-bench train --adopt``): a candidate trained from the shop's labels
waits as a file until someone who has read its cross-validated figures
adopts it. Every record names the model that judged it (name, file,
SHA-256), and replay finds it again by its hash: so a model file in the
station's folder is never replaced without its bytes kept under their hash
(:func:`write_model`), and the package's own models are never written.
"""

from __future__ import annotations

import datetime as dt
import os
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


def adopt_shipped() -> list[tuple[Path, Path]]:
    """Go back to the shipped models; the adopted file stays in the folder (old records name it).

    A file in the station's models folder named as a shipped one (a variant's own network trained with
    ``--models-dir`` into it) stands in for the shipped file (:func:`~edc_bench.verdict.classifier.variant_model_path`
    looks there first): it is renamed by its hash, where replay still finds it.

    Returns
    -------
    list of (pathlib.Path, pathlib.Path)
        The station's files set aside: (where it was, where it is now).
    """
    marker = station_models_dir() / ADOPTED_FILE
    moved: list[tuple[Path, Path]] = []
    try:
        if marker.exists():
            shutil.move(str(marker), str(marker.with_suffix(".json.previous")))
        for shipped in sorted(packaged_model_path().parent.glob("*.onnx")):
            stand_in = station_models_dir() / shipped.name
            if stand_in.is_file():
                kept = _hash_named(stand_in)
                if kept.exists():  # the same bytes kept already
                    stand_in.unlink()
                else:
                    os.replace(stand_in, kept)
                moved.append((stand_in, kept))
    except OSError as exc:
        raise ConfigError(f"cannot change the station's models folder {station_models_dir()}: {exc.strerror}; "
                          "make it writable for this user and run 'edc-bench train --adopt shipped' again") from None
    return moved


def _hash_named(path: Path) -> Path:
    """Where the bytes of model file ``path`` are kept once another file takes its name: ``STEM-SHA8.onnx`` beside
    it (the full hash should eight digits name another file)."""
    sha = file_sha256(path)
    for digits in (8, 64):
        kept = path.with_name(f"{path.stem}-{sha[:digits]}{path.suffix}")
        if not kept.exists() or file_sha256(kept) == sha:
            return kept
    raise ConfigError(f"{kept} exists with other bytes than {path}'s: move it out of the station's models folder")


def write_model(folder: Path, name: str, onnx_bytes: bytes) -> Path | None:
    """Write a trained model as ``folder/name``; the earlier file of that name, if the station's, kept by its hash.

    A model file in the station's models folder may have judged tests, and replay finds it by its SHA-256 there
    (:func:`~edc_bench.verdict.classifier.find_model`): before other bytes replace it, its own are copied to
    ``STEM-SHA8.onnx`` beside it. Elsewhere (``--models-dir`` a developer's folder) the file is replaced.

    Parameters
    ----------
    folder : pathlib.Path
        An existing folder, never one of the package's (the caller checks).
    name : str
        The file's name.
    onnx_bytes : bytes
        The model.

    Returns
    -------
    pathlib.Path or None
        The copy kept of the earlier file, or None if there was none to keep.

    Raises
    ------
    OSError
        If a file cannot be written (the command line names it in one line: a full disk's exit 74, else 2).
    """
    target = Path(folder) / name
    kept = None
    if target.resolve().parent == station_models_dir().resolve() and target.is_file() \
            and target.read_bytes() != onnx_bytes:
        kept = _hash_named(target)
        if not kept.exists():
            old = target.read_bytes()
            atomic_write(kept, lambda handle: handle.write(old))
    atomic_write(target, lambda handle: handle.write(onnx_bytes))
    return kept
