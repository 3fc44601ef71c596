"""The operator's name: asked once, remembered for this station (a shared login is not a person)."""

from __future__ import annotations

import json
from pathlib import Path

from edc_bench.paths import data_dir, write_json_atomic

FILE = "session.json"


def remembered_operator(folder: Path | None = None) -> str:
    """The operator last named at this station ("" if none, or the file is unreadable)."""
    path = (folder or data_dir()) / FILE
    try:
        value = json.loads(path.read_text(encoding="utf-8")).get("operator", "")
    except (OSError, ValueError, AttributeError):
        return ""
    return value if isinstance(value, str) else ""


def remember_operator(name: str, folder: Path | None = None) -> None:
    """Keep ``name`` as this station's operator for the next session (a failure to write is not fatal)."""
    try:
        write_json_atomic((folder or data_dir()) / FILE, {"operator": name})
    except OSError:
        pass
