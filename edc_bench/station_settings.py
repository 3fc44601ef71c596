"""The station's settings file: ``station.toml`` in the station's data folder, one section per concern
(``[station]``'s name and the shop it belongs to, ``[history]``'s time limits, ``[scan]``'s id patterns). A shop
edits it with any text editor; the session writes only the workshop into it, once (:func:`remember_workshop`)."""

from __future__ import annotations

import tomllib
from dataclasses import dataclass
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


#: ``[station]``'s keys, and how long each may be (characters)
_STATION_KEYS = {"name": 100, "shown_name": 100, "shop": 100, "shop_address": 300}


@dataclass(frozen=True)
class StationIdentity:
    """``[station]`` of the station's settings ("" where not set).

    Attributes
    ----------
    name : str
        What reports and the history call this station, instead of the PC's host name.
    shop, shop_address : str
        The workshop and its address: a record names them, the customer's page prints them.
    """

    name: str = ""
    shown_name: str = ""
    shop: str = ""
    shop_address: str = ""

    def for_customers(self, given: str | None = None) -> str:
        """The station's name as a customer's page prints it: ``given`` (``--station``), else ``shown_name``, else
        ``name``; "" when the shop named it nowhere (the PC's host name is never printed for a customer)."""
        return given or self.shown_name or self.name


def station_identity(data_folder: Path | None = None) -> StationIdentity:
    """``[station]`` of the station's settings: ``name`` (what the records and the history call this station,
    instead of the PC's host name), ``shown_name`` (what the customer's page calls it, if not ``name``), ``shop`` and
    ``shop_address`` (the customer's page prints them); "" where not set.

    Raises
    ------
    ConfigError
        For an unknown key, or a value that is not text of printable characters within its length, naming the file
        and the key.
    """
    section, path = settings_section("station", data_folder)
    unknown = sorted(set(section) - set(_STATION_KEYS))
    if unknown:
        raise ConfigError(f"the station's settings {path}: [station] has no key {unknown[0]!r}; its keys are "
                          f"{', '.join(_STATION_KEYS)}")
    out: dict[str, str] = {}
    for key, longest in _STATION_KEYS.items():
        value = section.get(key, "")
        # an address may take lines (a newline or '\n'); nothing else unprintable reaches a report or a history row
        lines_allowed = key == "shop_address"
        if (not isinstance(value, str) or len(value) > longest
                or not all(c.isprintable() or (c == "\n" and lines_allowed) for c in value)):
            raise ConfigError(f"the station's settings {path}: [station] {key} must be text of at most {longest} "
                              f"printable characters (an address may take lines), not {value!r}")
        out[key] = value.strip()
    return StationIdentity(**out)


def default_station() -> str:
    """This station's name: ``[station] name`` of its settings, else the PC's host name."""
    import socket

    return station_identity().name or socket.gethostname()


def workshop_asked(data_folder: Path | None = None) -> bool:
    """Whether the station's settings name the workshop (``[station] shop``, even as ""): the session asks for it
    once, where they do not. A settings file that cannot be read counts as asked (its own error is said where it is
    read)."""
    try:
        section, _ = settings_section("station", data_folder)
    except ConfigError:
        return True
    return "shop" in section


def remember_workshop(shop: str, address: str, data_folder: Path | None = None, shown_name: str | None = None
                      ) -> Path:
    """Write the workshop's name and address into ``[station]`` of the station's settings (created if missing; its
    other settings and comments kept), and ``shown_name`` (the station's name for customers) where given; the file.

    Raises
    ------
    ConfigError
        For a value :func:`station_identity` would refuse, or a settings file that cannot be read or written.
    """
    import tomlkit

    from edc_bench.paths import atomic_write

    shop, address = shop.strip(), address.strip()
    shown = None if shown_name is None else shown_name.strip()
    for key, value in (("shop", shop), ("shop_address", address), ("shown_name", shown or "")):
        longest = _STATION_KEYS[key]
        if len(value) > longest or not value.isprintable():
            raise ConfigError(f"the workshop's {key.replace('_', ' ')} must be at most {longest} printable "
                              "characters")
    path = settings_path(data_folder)
    try:
        document = tomlkit.parse(path.read_text(encoding="utf-8")) if path.is_file() else tomlkit.document()
    except (OSError, UnicodeDecodeError, ValueError) as exc:  # tomlkit's parse errors are ValueErrors
        raise ConfigError(f"the station's settings {path} cannot be read ({exc}): correct or remove it") from None
    station = document.get("station")
    if station is None:
        station = tomlkit.table()
        document["station"] = station
    written = {"shop": shop, "shop_address": address, **({} if shown is None else {"shown_name": shown})}
    for key, value in written.items():  # the keys of _STATION_KEYS; the file's other keys and comments kept
        station[key] = value
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        atomic_write(path, lambda f: f.write(tomlkit.dumps(document)), mode="w")
    except OSError as exc:
        raise ConfigError(f"the station's settings {path} cannot be written ({exc})") from None
    return path


__all__ = ["SETTINGS_FILE", "StationIdentity", "default_station", "remember_workshop", "workshop_asked",
           "settings_path", "settings_section", "station_identity"]
