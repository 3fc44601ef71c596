"""The example new pump type of docs/new-pump-type.md, which the tests and the page's walkthrough both use.

It is unlike the shipped variants: a force constant 2.2x the default's, a heavier rack, a stiffer spring,
another coil; the default's gains leave it too little margin.
"""

from __future__ import annotations

from pathlib import Path

NAME = "p-edc-newtype"

#: The lines of the shipped ``p-edc-default.toml`` that change, old -> new.
CHANGES = {
    'name = "p-edc-default"': f'name = "{NAME}"',
    'part_number = "PE-EDC-0001"': 'part_number = "PE-EDC-9001"',
    "mass_kg = 0.30": "mass_kg = 0.42",
    "spring_n_per_mm = 2.0": "spring_n_per_mm = 2.6",
    "force_constant_n_per_a = 5.0": "force_constant_n_per_a = 11.0",
    "resistance_ohm = 0.7\n": "resistance_ohm = 0.95\n",
    "resistance_min_ohm = 0.6": "resistance_min_ohm = 0.85",
    "resistance_max_ohm = 0.9": "resistance_max_ohm = 1.1",
    "inductance_mh = 1.0": "inductance_mh = 1.6",
}


def new_pump_type_text() -> str:
    """The new pump type's variant file: the shipped default's, with :data:`CHANGES`.

    Raises
    ------
    ValueError
        If the shipped default no longer holds a line that changes (update :data:`CHANGES`).
    """
    from edc_bench.config.loader import variant_file

    text = variant_file("p-edc-default").read_text(encoding="utf-8")
    for old, new in CHANGES.items():
        if old not in text:
            raise ValueError(f"p-edc-default.toml no longer holds {old!r}: update edc_bench.testing.new_pump_type")
        text = text.replace(old, new)
    return text


def write_new_pump_type(folder: Path) -> Path:
    """Write the new pump type's variant file (``p-edc-newtype.toml``) into ``folder``; returns its path."""
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"{NAME}.toml"
    path.write_text(new_pump_type_text(), encoding="utf-8")
    return path
