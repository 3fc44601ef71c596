"""The station's settings file: ``station.toml`` in the station's data folder, one section per concern
(``[history]``'s time limits, ``[scan]``'s id patterns). Read only; a shop edits it with any text editor."""

from __future__ import annotations

import tomllib
from pathlib import Path
from typing import Any

from edc_bench.errors import ConfigError

#: The settings file in the station's data folder.
SETTINGS_FILE = "station.toml"


def settings_path(data_folder: Path | None = None) -> Path:
    """Where the station's settings are (the file need not exist)."""
    if data_folder is None:
        from edc_bench.paths import data_dir

        data_folder = data_dir(create=False)
    return Path(data_folder) / SETTINGS_FILE


def settings_section(name: str, data_folder: Path | None = None) -> tuple[dict[str, Any], Path]:
    """Section ``[name]`` of the station's settings ({} where the file or the section is missing), and the file's path
    (for messages that name it).

    Raises
    ------
    ConfigError
        For a file that cannot be read or parsed, or a ``name`` that is not a section, naming the file.
    """
    path = settings_path(data_folder)
    if not path.is_file():
        return {}, path
    try:
        section = tomllib.loads(path.read_text(encoding="utf-8")).get(name, {})
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise ConfigError(f"the station's settings {path} cannot be read ({exc}): correct or remove it") from None
    if not isinstance(section, dict):
        raise ConfigError(f"the station's settings {path}: [{name}] is not a section; write it as a [{name}] table")
    return section, path


__all__ = ["SETTINGS_FILE", "settings_path", "settings_section"]
