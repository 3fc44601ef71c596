r"""What a scanned id looks like at this shop: a pattern per field, from ``[scan]`` in the station's settings::

    [scan]
    valve_id = 'V-\d{5}'          # a regular expression the whole line must match
    pump_serial = 'PS-\d{4,6}'
    part_number = 'PE-EDC-\d{4}'  # a line like this that names no pump type is refused, not taken as an id
    job = 'JOB-\d{6}'             # a line like this, at any prompt, is the job or vehicle reference of the valve

A line that does not fit is not refused outright (a label may be new): the session asks for it to be scanned
again to take it as it is. Where the shop sets no pattern, an id is ASCII letters, digits and ``. _ - / = + :``; a
line with anything else (``;``, ``@``, ``#``, spaces, symbols, letters such as ``ß`` that a scanner set to another
keyboard layout types for ``-``) is asked about the same way. Patterns match ASCII only (``\d`` is 0-9).
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field

from edc_bench.errors import ConfigError

#: The fields a shop may give a pattern for, as they are named in ``[scan]`` and said on screen.
FIELDS = {"valve_id": "valve id", "pump_serial": "pump serial", "part_number": "part number",
          "job": "job or vehicle reference"}
#: An id where the shop sets no pattern: a letter or digit, then letters, digits and the marks labels use.
DEFAULT_ID = re.compile(r"[^\W_][\w./=+:-]*", re.ASCII)
_ID_CHARACTER = re.compile(r"[\w./=+:-]", re.ASCII)


@dataclass(frozen=True)
class ScanRules:
    """The shop's patterns (a field without one takes :data:`DEFAULT_ID`; ``part_number`` none)."""

    patterns: dict[str, re.Pattern[str]] = field(default_factory=dict)

    def misfit(self, field_name: str, text: str) -> str | None:
        """Why ``text`` does not look like a ``field_name`` here (None: it does)."""
        pattern = self.patterns.get(field_name)
        what = FIELDS[field_name]
        if pattern is not None:
            if pattern.fullmatch(text):
                return None
            return f"{text!r} does not look like a {what} here (the station's pattern {pattern.pattern})"
        if DEFAULT_ID.fullmatch(text):
            return None
        odd = "".join(dict.fromkeys(c for c in text if not _ID_CHARACTER.fullmatch(c)))
        shown = " ".join("space" if c == " " else repr(c) for c in odd) if odd else "its first character"
        return f"{text!r} has characters an id rarely has ({shown})"

    def looks_like_part_number(self, text: str) -> bool:
        """True where the shop's part-number pattern matches ``text``."""
        return self._matches("part_number", text)

    def looks_like_job(self, text: str) -> bool:
        """True where the shop's job-reference pattern matches ``text`` (no pattern: no line is a job reference)."""
        return self._matches("job", text)

    def _matches(self, field_name: str, text: str) -> bool:
        pattern = self.patterns.get(field_name)
        return pattern is not None and pattern.fullmatch(text) is not None


def scan_rules(section: dict[str, object], where: str) -> ScanRules:
    """The rules of a ``[scan]`` section.

    Raises
    ------
    ConfigError
        For an unknown key or a pattern that is not a regular expression, naming ``where``.
    """
    patterns: dict[str, re.Pattern[str]] = {}
    for key, value in section.items():
        if key not in FIELDS:
            raise ConfigError(f"{where}: [scan] {key} is not a field; the fields are {', '.join(FIELDS)}")
        if not isinstance(value, str) or not value:
            raise ConfigError(f"{where}: [scan] {key} = {value!r}: give a regular expression as a string, e.g. "
                              f"{key} = 'V-\\d{{5}}'")
        try:
            patterns[key] = re.compile(value, re.ASCII)
        except re.error as exc:
            raise ConfigError(f"{where}: [scan] {key} = {value!r} is not a regular expression ({exc}); in TOML "
                              "write it in single quotes, e.g. 'V-\\d{5}'") from None
    return ScanRules(patterns)


def station_scan_rules() -> ScanRules:
    """The station's rules (``[scan]`` in its settings file; none set: :data:`DEFAULT_ID` for every id)."""
    from edc_bench.station_settings import settings_section

    section, path = settings_section("scan")
    return scan_rules(section, str(path))


__all__ = ["DEFAULT_ID", "FIELDS", "ScanRules", "scan_rules", "station_scan_rules"]
