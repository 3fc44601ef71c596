"""Datasets of identified features with their ground truth, as files with provenance.

A dataset is the batch path run over a simulated population of one or more
variants: per valve the identified af and a1, their ratios to the variant's
baseline, whether the test converged, and the physical truth (resisting
force, label). Files are ``.npz`` with a ``provenance`` JSON entry (variants,
seed, counts, generator version, content hash).
"""

from __future__ import annotations

import hashlib
import json
import os
import zipfile
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any

import numpy as np

from edc_bench import __version__
from edc_bench.config import load_variant
from edc_bench.config.models import Variant
from edc_bench.errors import ConfigError
from edc_bench.paths import atomic_write
from edc_bench.physics.valve import ValveSpec
from edc_bench.physics.wear import is_faulty, resisting_force_n
from edc_bench.population.batch import run_batch
from edc_bench.population.batch_stop import BatchStopRule
from edc_bench.population.valves import draw_population
from edc_bench.verdict.baseline import load_baseline

GENERATOR_VERSION = 1
#: The significant digits a value counts with in :meth:`Dataset.content_hash`.
HASH_SIGNIFICANT_DIGITS = 6
CHUNK = 500


@dataclass(frozen=True)
class DatasetColumns:
    """A dataset's columns, one row per simulated bench test (each an array of the same length).

    Attributes
    ----------
    af, a1 : numpy.ndarray
        The identified features (V; V s/mm).
    af_rel, a1_rel : numpy.ndarray
        The features over the variant's new-valve baseline: what the classifier judges.
    faulty : numpy.ndarray
        The physical truth, the label (:func:`~edc_bench.physics.wear.is_faulty`).
    converged : numpy.ndarray
        Whether the test's estimate converged (training may keep only these).
    resisting_force_n, clearance_mm, roughness : numpy.ndarray
        The valve as simulated: its resisting force (N), clearance (mm) and roughness.
    variant_index : numpy.ndarray
        Which of the provenance's variants the valve was drawn for.
    seed : numpy.ndarray
        The test's noise seed.
    """

    af: np.ndarray
    a1: np.ndarray
    af_rel: np.ndarray
    a1_rel: np.ndarray
    faulty: np.ndarray
    converged: np.ndarray
    resisting_force_n: np.ndarray
    clearance_mm: np.ndarray
    roughness: np.ndarray
    variant_index: np.ndarray
    seed: np.ndarray

    def items(self) -> list[tuple[str, np.ndarray]]:
        """(name, column) in :data:`COLUMNS`'s order: the file's entries and the content hash's order."""
        return [(name, getattr(self, name)) for name in COLUMNS]

    @classmethod
    def labelled(cls, af_rel: np.ndarray, a1_rel: np.ndarray, faulty: np.ndarray, af: np.ndarray | None = None,
                 a1: np.ndarray | None = None) -> DatasetColumns:
        """Rows known only by their relative features and label (a study's patterns, a shop's teardowns): every
        row converged, the simulation's columns zero."""
        n = len(faulty)
        zeros = np.zeros(n)
        return cls(af=zeros if af is None else af, a1=zeros if a1 is None else a1, af_rel=af_rel, a1_rel=a1_rel,
                   faulty=faulty, converged=np.ones(n, bool), resisting_force_n=zeros, clearance_mm=zeros,
                   roughness=zeros, variant_index=zeros, seed=zeros)

    @classmethod
    def concatenated(cls, parts: Sequence[DatasetColumns]) -> DatasetColumns:
        """The rows of ``parts``, one after the other."""
        return cls(**{name: np.concatenate([getattr(part, name) for part in parts]) for name in COLUMNS})


#: The columns' names, in the order a dataset file holds them and its content hash counts them.
COLUMNS = tuple(f.name for f in fields(DatasetColumns))


def update_digest(digest: "hashlib._Hash", name: str, values: np.ndarray) -> None:
    """Add a named column to a content hash: floats as text to :data:`HASH_SIGNIFICANT_DIGITS` significant
    digits (so that the last bits of another CPU's or BLAS's arithmetic do not change it), integers and
    booleans as integers."""
    digest.update(name.encode())
    column = np.asarray(values)
    if np.issubdtype(column.dtype, np.floating):
        text = np.char.mod(f"%.{HASH_SIGNIFICANT_DIGITS - 1}e", column)
    else:
        text = column.astype(np.int64).astype(str)
    digest.update(",".join(text.ravel().tolist()).encode())


@dataclass
class Dataset:
    """Columns of one dataset (one row per simulated bench test)."""

    columns: DatasetColumns
    provenance: dict[str, Any] = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.columns.af)

    @property
    def features(self) -> np.ndarray:
        """(N, 2) relative features [af/af0, a1/a1_0]."""
        return np.column_stack([self.columns.af_rel, self.columns.a1_rel])

    @property
    def labels(self) -> np.ndarray:
        """(N,) 1 for faulty, 0 for reusable."""
        return self.columns.faulty.astype(int)

    def content_hash(self) -> str:
        """SHA-256 of the columns (order and values), each value to :data:`HASH_SIGNIFICANT_DIGITS` digits.

        The same simulation on another CPU or BLAS differs in the last bits (about 1e-13 relative); a changed
        simulation moves the features by far more than a millionth. Hashing the values as text to six
        significant digits names the data, not the machine that computed it.
        """
        digest = hashlib.sha256()
        for name, column in self.columns.items():
            update_digest(digest, name, column)
        return digest.hexdigest()

    def save(self, path: Path) -> None:
        """Write the dataset (atomically) with its provenance."""
        provenance = {**self.provenance, "content_sha256": self.content_hash(), "rows": len(self)}
        atomic_write(Path(path), lambda f: np.savez_compressed(
            f, provenance=np.array(json.dumps(provenance, sort_keys=True)), **dict(self.columns.items())))

    @classmethod
    def load(cls, path: Path) -> Dataset:
        """Read a dataset written by :meth:`save`, checking its hash."""
        try:
            with np.load(Path(path)) as data:
                columns = DatasetColumns(**{name: data[name] for name in COLUMNS})
                provenance = json.loads(str(data["provenance"]))
        except (OSError, KeyError, ValueError, EOFError, zipfile.BadZipFile) as exc:  # a damaged or foreign file
            raise ConfigError(f"{path}: not an edc-bench dataset ({exc})") from None
        dataset = cls(columns, provenance)
        if provenance.get("content_sha256") != dataset.content_hash():
            raise ConfigError(f"{path}: content does not match its recorded hash; regenerate it")
        return dataset


def _chunk_worker(args: tuple[Variant, list[ValveSpec], list[int], bool]) -> tuple[np.ndarray, np.ndarray]:
    variant, valves, seeds, early_stop = args
    result = run_batch(variant, valves, seeds, stop=BatchStopRule.shipped(variant) if early_stop else None)
    return result.parameters[:, [5, 2]], result.trusted


def run_population(variant: Variant, valves: list[ValveSpec], seeds: list[int], workers: int, *,
                   early_stop: bool = False, chunk: int = CHUNK) -> tuple[np.ndarray, np.ndarray]:
    """Batch tests of ``valves`` in chunks of ``chunk`` valves, over ``workers`` processes.

    With ``early_stop``, each test stops where the bench's would (the packaged classifier and baseline,
    :class:`~edc_bench.population.batch_stop.BatchStopRule`), with its figures then; by default every test runs its
    full length (training data: the classifier is what decides a stop).

    Returns
    -------
    (numpy.ndarray, numpy.ndarray)
        Features ``[af, a1]`` per valve, and whether each converged.
    """
    jobs = [(variant, valves[i:i + chunk], seeds[i:i + chunk], early_stop) for i in range(0, len(valves), chunk)]
    if workers > 1 and len(jobs) > 1:
        with ProcessPoolExecutor(max_workers=workers) as pool:
            parts = list(pool.map(_chunk_worker, jobs))
    else:
        parts = [_chunk_worker(job) for job in jobs]
    return np.concatenate([p[0] for p in parts]), np.concatenate([p[1] for p in parts])


def make_dataset(variant_names: Sequence[str], count_per_variant: int, seed: int,
                 workers: int | None = None) -> Dataset:
    """Simulate a population per variant through the batch path.

    Parameters
    ----------
    variant_names : sequence of str
        Variants to draw valves for.
    count_per_variant : int
        Valves (one test each) per variant.
    seed : int
        Seed of the populations and of the sensor noise; same seed, same dataset.
    workers : int, optional
        Processes to spread chunks over (default: all cores).
    """
    workers = workers or os.cpu_count() or 1
    parts: list[DatasetColumns] = []
    for v_index, name in enumerate(variant_names):
        variant = load_variant(name)
        baseline = load_baseline(variant, station=False)  # simulated features: the shipped simulated baseline
        population_seed = seed * 1000 + v_index
        valves = draw_population(variant, count_per_variant, population_seed)
        seeds = [population_seed * 100_000 + n for n in range(count_per_variant)]
        features, converged = run_population(variant, valves, seeds, workers)
        parts.append(DatasetColumns(
            af=features[:, 0], a1=features[:, 1], af_rel=features[:, 0] / baseline.af_v,
            a1_rel=features[:, 1] / baseline.a1_v_s_per_mm, faulty=np.array([is_faulty(variant, v) for v in valves]),
            converged=converged, resisting_force_n=np.array([resisting_force_n(variant, v) for v in valves]),
            clearance_mm=np.array([v.clearance_mm for v in valves]), roughness=np.array([v.roughness for v in valves]),
            variant_index=np.full(count_per_variant, v_index), seed=np.array(seeds)))
    columns = DatasetColumns.concatenated(parts)
    provenance = {"variants": list(variant_names), "count_per_variant": count_per_variant, "seed": seed,
                  "generator_version": GENERATOR_VERSION, "edc_bench_version": __version__}
    return Dataset(columns, provenance)


def cached_dataset(variant_names: Sequence[str], count_per_variant: int, seed: int,
                   workers: int | None = None) -> tuple[Dataset, bool]:
    """:func:`make_dataset`, kept in the cache folder so the next call with the same arguments loads it.

    Returns the dataset and whether it came from the cache. The cache key holds the arguments, the
    generator and edc-bench versions and the variants' content, so a changed variant simulates again.
    """
    from edc_bench.paths import cache_dir

    key = json.dumps({"variants": [load_variant(name).model_dump(mode="json") for name in variant_names],
                      "count": count_per_variant, "seed": seed, "generator": GENERATOR_VERSION,
                      "version": __version__}, sort_keys=True)
    path = cache_dir() / "datasets" / f"population-{hashlib.sha256(key.encode()).hexdigest()[:16]}.npz"
    if path.exists():
        try:
            return Dataset.load(path), True
        except ConfigError:
            pass  # a damaged cache entry is simulated again
    dataset = make_dataset(variant_names, count_per_variant, seed, workers)
    from edc_bench.runtime.signals import stop_if_interrupted

    stop_if_interrupted()  # a population a library ran on after Ctrl-C is not kept for next time
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        dataset.save(path)
    except OSError:
        pass  # a cache that cannot be written costs time, not results
    return dataset, False
