"""A record as the test wrote it: record.json's manifest of SHA-256 digests, and its check.

When a test writes its record folder, record.json gets an ``integrity`` section: the digest of each file the
test wrote beside it (the trace, the CAN log, the figure) and of each of record.json's own top-level sections.
Every reader checks it (:func:`altered`) and refuses a record that changed after the test, naming what
changed: a verdict edited from PASS to FAIL is ``record.json's 'verdict'``, a replaced log is ``can.log``.

The digests catch a record changed by hand or by a tool, or damaged on a disk; they carry no secret, so
someone who rewrites the digests too is not stopped (a signed record needs a key the station keeps: not here).
Records of schema 4 and older carry no manifest and are read as before.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path
from typing import Any

#: The record schema from which record.json must carry its manifest.
INTEGRITY_SCHEMA = 5
ALGORITHM = "sha256"


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


def altered(doc: dict[str, Any], folder: Path) -> list[str]:
    """What changed in a record since its test wrote it (empty: nothing, or a record too old to carry a manifest).

    ``doc`` is record.json's content as read, before any upgrade.
    """
    try:
        schema = int(doc.get("schema") or 0)
    except (TypeError, ValueError):
        schema = INTEGRITY_SCHEMA  # a damaged schema field: held to its manifest like any new record
    if schema < INTEGRITY_SCHEMA and "integrity" not in doc:
        return []  # an older record: nothing to check it against (a lowered schema with a manifest is checked)
    kept = doc.get("integrity")
    if not isinstance(kept, dict) or not isinstance(kept.get("sections"), dict) \
            or not isinstance(kept.get("files"), dict):
        return ["record.json's integrity manifest (removed or damaged)"]
    changes = []
    sections = kept["sections"]
    for key in sorted(set(doc) - {"integrity"} | set(sections)):
        if key not in doc:
            changes.append(f"record.json's {key!r} (removed)")
        elif sections.get(key) != section_digest(doc[key]):
            changes.append(f"record.json's {key!r}" + (" (added)" if key not in sections else ""))
    for name, digest in sorted(kept["files"].items()):
        path = folder / name
        if not path.is_file():
            changes.append(f"{name} (missing)")
        elif file_digest(path) != digest:
            changes.append(name)
    return changes


__all__ = ["INTEGRITY_SCHEMA", "altered", "file_digest", "manifest", "section_digest"]
