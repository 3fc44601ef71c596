"""Find and load pump variant files, with errors a technician can act on."""

from __future__ import annotations

import tomllib
from pathlib import Path
from typing import Any

from pydantic import ValidationError

from edc_bench.config.models import Variant
from edc_bench.errors import ConfigError

DEFAULT_VARIANT = "p-edc-default"


def variant_dirs() -> list[Path]:
    """Folders searched for variant files, first match wins.

    A non-editable install carries the library inside the package
    (``edc_bench/_variants``); a source checkout reads ``configs/`` beside the
    package. Last comes the station's own folder (:func:`station_variant_dir`),
    where a technician adds the variants of the pumps the shop sees; the
    shipped names cannot be shadowed from there.
    """
    package_dir = Path(__file__).resolve().parent.parent
    dirs = [package_dir / "_variants", package_dir.parent / "configs", station_variant_dir()]
    return [d for d in dirs if d.is_dir()]


def is_shipped(path: Path) -> bool:
    """True for a file of the shipped variant library (the package's, or ``configs/`` of a source checkout)."""
    package_dir = Path(__file__).resolve().parent.parent
    folder = Path(path).resolve().parent
    return folder in (package_dir / "_variants", package_dir.parent / "configs")


def station_variant_dir() -> Path:
    """The station's variant folder: ``EDC_BENCH_VARIANTS_DIR``, else ``variants`` in the data folder."""
    import os

    configured = os.environ.get("EDC_BENCH_VARIANTS_DIR")
    if configured:
        return Path(configured)
    from edc_bench.paths import data_dir

    return data_dir(create=False) / "variants"  # looking for variants creates nothing


def available_variants() -> dict[str, Path]:
    """Variant names (file stems) and their files, from :func:`variant_dirs`."""
    found: dict[str, Path] = {}
    for folder in variant_dirs():
        for path in sorted(folder.glob("*.toml")):
            found.setdefault(path.stem, path)
    return found


def _describe_location(loc: tuple[Any, ...]) -> str:
    parts = [str(p) for p in loc]
    if not parts:
        return "variant"
    head = f"[{parts[0]}]"
    return head + ("." + ".".join(parts[1:]) if len(parts) > 1 else "")


def format_validation_error(source: str, error: ValidationError, data: dict[str, Any] | None = None) -> str:
    """Turn a pydantic error into lines naming file, field, value and expectation.

    Parameters
    ----------
    source : str
        File name (or other origin) shown at the start of each line.
    error : pydantic.ValidationError
        The validation error.
    data : dict, optional
        The raw input, used to list the allowed keys for an unknown key.

    Returns
    -------
    str
        One line per problem.
    """
    lines = []
    for item in error.errors(include_url=False):
        loc = tuple(item.get("loc", ()))
        where = _describe_location(loc)
        kind = item.get("type", "")
        value = item.get("input")
        if kind == "extra_forbidden" and loc[-2:] in RETIRED_KEYS:
            lines.append(f"{source}: {where}: {RETIRED_KEYS[loc[-2:]]}")
        elif kind == "extra_forbidden":
            allowed = _allowed_keys(loc[:-1])
            hint = f"; expected one of: {', '.join(allowed)}" if allowed else ""
            lines.append(f"{source}: {where}: unknown key{hint}")
        elif kind == "missing":
            lines.append(f"{source}: {where}: required key is missing")
        else:
            message = str(item.get("msg", "invalid")).removeprefix("Value error, ")
            shown = "" if isinstance(value, dict) else f" = {value!r}"
            lines.append(f"{source}: {where}{shown}: {message}")
    return "\n".join(lines)


#: Keys an older edc-bench read, and why a file should no longer give them.
RETIRED_KEYS: dict[tuple[Any, ...], str] = {
    ("acceptance", "max_period_spread_rel"): (
        "no longer a setting: the spread of af and a1 from period to period is noise (a USB adapter's timing "
        "raises it), which widens their uncertainty and the verdict waits for; a pump the model does not fit is "
        "found by the residual that repeats every period (max_residual_ratio) and the gain variation. Delete the "
        "line"),
}


def without_retired_keys(data: dict[str, Any]) -> dict[str, Any]:
    """``data`` (a variant as a record stores it) without :data:`RETIRED_KEYS`: a test recorded by an older
    edc-bench replays under today's rules."""
    out = dict(data)
    for section, key in RETIRED_KEYS:
        if isinstance(out.get(section), dict) and key in out[section]:
            out[section] = {k: v for k, v in out[section].items() if k != key}
    return out


def _allowed_keys(loc: tuple[Any, ...]) -> list[str]:
    model: Any = Variant
    for part in loc:
        field = model.model_fields.get(str(part)) if hasattr(model, "model_fields") else None
        if field is None:
            return []
        model = field.annotation
    return sorted(model.model_fields) if hasattr(model, "model_fields") else []


def with_changes(variant: Variant, changes: dict[str, dict[str, Any]], source: str) -> Variant:
    """``variant`` with some keys replaced (``{section: {key: value}}``), validated again as a whole.

    ``source`` names the changed variant in error messages (e.g. "command-line overrides").
    """
    data = variant.model_dump(mode="python")
    for section, values in changes.items():
        data[section].update(values)
    changed = parse_variant(data, f"variant {variant.name} with {source}")
    changed._source_file = variant.source_file
    return changed


def parse_variant(data: dict[str, Any], source: str = "<variant>") -> Variant:
    """Validate a variant given as a dict (the parsed TOML).

    Raises
    ------
    ConfigError
        With one line per problem, naming ``source``, the field and the value.
    """
    try:
        return Variant.model_validate(data)
    except ValidationError as exc:
        raise ConfigError(format_validation_error(source, exc, data)) from None


def load_variant(name_or_path: str | Path | None = None) -> Variant:
    """Load a pump variant by name or by TOML file path.

    Parameters
    ----------
    name_or_path : str or pathlib.Path, optional
        A variant name from the library (``edc-bench variants``), a part
        number, or a path to a ``.toml`` file. The default variant if omitted.

    Returns
    -------
    Variant
        The validated variant.

    Raises
    ------
    ConfigError
        If no such variant exists, the file cannot be read or parsed, or a
        value is invalid.
    """
    path = variant_file(name_or_path)
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise ConfigError(f"{path}: cannot read variant file ({exc.strerror})") from None
    data = _variant_data(path, raw)
    if not data:
        raise ConfigError(f"{path}: the variant file is empty; copy configs/p-edc-default.toml and edit it "
                          "(docs/variants.md)")
    variant = parse_variant(data, str(path))
    variant._source_file = str(path)
    return variant


def _variant_data(path: Path, raw: bytes) -> dict[str, Any]:
    """A variant file's bytes as TOML data; UTF-8 text (a byte-order mark, as Windows editors write, is allowed).

    Raises
    ------
    ConfigError
        In one line, for a file that is binary, in another encoding or not TOML, saying what to do.
    """
    if raw.startswith((b"\xff\xfe", b"\xfe\xff")):
        raise ConfigError(f"{path}: the variant file is UTF-16 text; save it as UTF-8 (docs/variants.md)")
    if b"\x00" in raw:
        raise ConfigError(f"{path}: not a variant file: it holds binary data (NUL bytes); give a TOML text file "
                          "such as configs/p-edc-default.toml")
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = raw[:exc.start].count(b"\n") + 1
        raise ConfigError(f"{path}: not UTF-8 text (byte 0x{raw[exc.start]:02x} on line {line}, e.g. a Latin-1 "
                          "umlaut); save the file as UTF-8") from None
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{path}: not valid TOML: {exc}") from None


def variant_argument(variant: Variant) -> str:
    """How to name ``variant`` on the command line: its name if the library finds it by name, else its file."""
    library_file = available_variants().get(variant.name)
    if variant.source_file is None or (library_file is not None
                                       and library_file.resolve() == Path(variant.source_file).resolve()):
        return variant.name
    return variant.source_file


def variant_file(name_or_path: str | Path | None = None) -> Path:
    """The file :func:`load_variant` reads for ``name_or_path`` (the default variant's if None).

    Raises
    ------
    ConfigError
        If there is no such variant.
    """
    key = str(name_or_path) if name_or_path is not None else DEFAULT_VARIANT
    candidate = Path(key)
    if candidate.suffix == ".toml" or "/" in key or candidate.exists():
        if candidate.is_dir():
            raise ConfigError(f"variant file {key!r} is a folder; give a .toml file in it, a name or a part number "
                              "('edc-bench variants' lists them)")
        if candidate.exists() and not candidate.is_file():
            raise ConfigError(f"variant file {key!r} is a device or other special file; give a .toml file")
        if not candidate.is_file():
            raise ConfigError(f"variant file {key!r} does not exist")
        return candidate
    library = available_variants()
    if key in library:
        return library[key]
    for path in library.values():
        try:
            pump = tomllib.loads(path.read_text(encoding="utf-8")).get("pump", {})
        except (OSError, ValueError):  # unreadable, not UTF-8, not TOML: 'edc-bench variants' says why
            continue
        if pump.get("part_number") == key:
            return path
    names = ", ".join(sorted(library)) or "(none found)"
    raise ConfigError(f"unknown variant {key!r}: give a name ({names}), a part number, or a path to a .toml file")
