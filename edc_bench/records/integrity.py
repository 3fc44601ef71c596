"""A record as the test wrote it: record.json's manifest of SHA-256 digests, and its check.

When a test writes its record folder, record.json gets an ``integrity`` section: the digest of each file the
test wrote beside it (the trace, the CAN log, the figure) and of each of record.json's own top-level sections.
Every reader checks it (:func:`altered`) and refuses a record that changed after the test, naming what
changed: a verdict edited from PASS to FAIL is ``record.json's 'verdict'``, a replaced log is ``can.log``.

The digests catch a record changed by hand or by a tool, or damaged on a disk; they carry no secret, so
someone who rewrites the digests too is not stopped (a signed record needs a key the station keeps: not here);
whether such a record's verdict still follows from its own figures is :mod:`~edc_bench.records.consistency`'s
question.

Records of schema 4 and older carry no manifest and are read as before. A record whose ``schema`` says 4 or
older but which holds what only a writer of manifests writes (:func:`manifest_writer_signs`: a key added in
schema 5 or later, or an edc-bench version released after manifests came) had its manifest removed: it is
altered, whatever its schema says. A record made to look old in every key (those keys removed too, its version
left at 0.1.0, which wrote both kinds) cannot be told from a genuine old one by the record alone: the history's
digest of the record as first indexed is what catches it.
"""

from __future__ import annotations

import hashlib
import json
import re
from pathlib import Path
from typing import Any

from edc_bench.records.writer import RECORD_FILE

#: The record schema from which record.json must carry its manifest.
INTEGRITY_SCHEMA = 5
ALGORITHM = "sha256"

#: The last edc-bench version that wrote records without a manifest; it also wrote them with one (the version was
#: 0.1.0 before and after schema 5, 2026-11-26), so only a later version says "a writer of manifests".
LAST_VERSION_WITHOUT_MANIFEST = (0, 1, 0)

#: Keys of record.json (a path of nested keys) that only writers of manifests have written: each came with
#: schema 5 or later (records/writer.py's schema list; git log -S on each), so no record of schema 4 holds one.
MANIFEST_ERA_KEYS: tuple[tuple[str, ...], ...] = (
    ("test_id",),  # schema 8: the test's own id
    ("retest",),  # the MARGINAL retest (2026-11-26, schema 5): written in every record since, null when none
    ("stop", "misfit_half_width_rel"),  # the early stop's interval parts (#37, schema 5 and 7)
    ("stop", "baseline_half_width_rel"),
    ("stop", "residual_half_width_rel"),
    ("identification", "model_fit", "core_shift_rel"),  # the core rows' fit (#37, schema 5)
)


def section_digest(value: Any) -> str:
    """The digest of one section of record.json, over its canonical JSON (keys sorted, no spaces): the same for
    the value written and the value read back."""
    text = json.dumps(value, sort_keys=True, separators=(",", ":"), ensure_ascii=False, allow_nan=True)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def file_digest(path: Path) -> str:
    """SHA-256 of a file's bytes."""
    digest = hashlib.sha256()
    with open(path, "rb") as handle:
        for block in iter(lambda: handle.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def manifest(doc: dict[str, Any], folder: Path, files: list[str]) -> dict[str, Any]:
    """The ``integrity`` section for record.json ``doc`` (already JSON-safe) and the ``files`` written in
    ``folder``."""
    return {"algorithm": ALGORITHM,
            "files": {name: file_digest(folder / name) for name in files if (folder / name).is_file()},
            "sections": {key: section_digest(value) for key, value in doc.items() if key != "integrity"}}


class Change(str):
    """One change found in a record, as a person reads it (``record.json's 'verdict'``), and the file it is in
    (``file``): a caller asks which file, never the words."""

    file: str

    def __new__(cls, words: str, file: str) -> Change:
        made = super().__new__(cls, words)
        made.file = file
        return made


def altered(doc: dict[str, Any], folder: Path) -> list[Change]:
    """What changed in a record since its test wrote it (empty: nothing, or a record too old to carry a manifest).

    ``doc`` is record.json's content as read, before any upgrade.
    """
    try:
        schema = int(doc.get("schema") or 0)
    except (TypeError, ValueError):
        schema = INTEGRITY_SCHEMA  # a damaged schema field: held to its manifest like any new record
    if schema < INTEGRITY_SCHEMA and "integrity" not in doc:
        signs = manifest_writer_signs(doc)
        if signs:  # a lowered schema, the manifest removed: the record says who wrote it
            shown = " and ".join(signs[:2]) + (f" (and {len(signs) - 2} more)" if len(signs) > 2 else "")
            return [Change(f"record.json's integrity manifest (removed: its schema says {doc.get('schema')!r}, but it "
                           f"holds {shown}, written only by an edc-bench that writes a manifest)", RECORD_FILE)]
        return []  # an older record: nothing to check it against (a lowered schema with a manifest is checked)
    kept = doc.get("integrity")
    if not isinstance(kept, dict) or not isinstance(kept.get("sections"), dict) \
            or not isinstance(kept.get("files"), dict):
        return [Change("record.json's integrity manifest (removed or damaged)", RECORD_FILE)]
    changes: list[Change] = []
    sections = kept["sections"]
    for key in sorted(set(doc) - {"integrity"} | set(sections)):
        if key not in doc:
            changes.append(Change(f"record.json's {key!r} (removed)", RECORD_FILE))
        elif sections.get(key) != section_digest(doc[key]):
            added = " (added)" if key not in sections else ""
            changes.append(Change(f"record.json's {key!r}{added}", RECORD_FILE))
    for name, digest in sorted(kept["files"].items()):
        path = folder / name
        if not path.is_file():
            changes.append(Change(f"{name} (missing)", name))
        elif file_digest(path) != digest:
            changes.append(Change(name, name))
    return changes


def manifest_writer_signs(doc: dict[str, Any]) -> list[str]:
    """What in record.json ``doc`` says an edc-bench that writes integrity manifests wrote it, its ``schema`` aside.

    Returns
    -------
    list of str
        Each sign in words (``'test_id'``, ``software_version 0.2.0``); empty when the record holds none
        (a genuine older record, or one made to look old in every key: the record alone cannot tell those apart).
    """
    signs = []
    for path in MANIFEST_ERA_KEYS:
        value: Any = doc
        for key in path:
            value = value.get(key, _ABSENT) if isinstance(value, dict) else _ABSENT
        if value is not _ABSENT:
            signs.append(repr(".".join(path)))
    version = _version(doc.get("software_version"))
    if version is not None and version > LAST_VERSION_WITHOUT_MANIFEST:
        signs.append(f"software_version {doc['software_version']}")
    return signs


_ABSENT = object()


def _version(text: Any) -> tuple[int, int, int] | None:
    """The release of an edc-bench version string (``0.2.0``, ``0.2.0.dev1``, ``0.1.0+local``), or None."""
    match = re.match(r"\s*v?(\d+)\.(\d+)(?:\.(\d+))?", text) if isinstance(text, str) else None
    return None if match is None else (int(match[1]), int(match[2]), int(match[3] or 0))


__all__ = ["INTEGRITY_SCHEMA", "LAST_VERSION_WITHOUT_MANIFEST", "MANIFEST_ERA_KEYS", "altered", "file_digest",
           "manifest", "manifest_writer_signs", "section_digest"]
