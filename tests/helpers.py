"""Plain helpers shared by the test modules: ``from helpers import ...`` (``pythonpath = ["tests"]``, pyproject.toml)."""

from __future__ import annotations

import subprocess
import sys
from collections.abc import Mapping
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent  # the repository's root (configs/, docs/, ...)


def edc_bench(*args: str, cwd: Path | None = None, timeout: float = 600,
              env: Mapping[str, str] | None = None) -> subprocess.CompletedProcess:
    """Run ``edc-bench ARGS`` (``python -m edc_bench``) in a subprocess; output captured as text."""
    return subprocess.run([sys.executable, "-m", "edc_bench", *args], capture_output=True, text=True, cwd=cwd,
                          timeout=timeout, env=env)


#: A pump type unlike the shipped ones (docs/new-pump-type.md): force constant 2.2x the default's, a heavier
#: rack, a stiffer spring, another coil. The default's gains leave it too little margin.
NEW_PUMP_TYPE_CHANGES = {
    'name = "p-edc-default"': 'name = "p-edc-newtype"',
    'part_number = "PE-EDC-0001"': 'part_number = "PE-EDC-9001"',
    "mass_kg = 0.30": "mass_kg = 0.42",
    "spring_n_per_mm = 2.0": "spring_n_per_mm = 2.6",
    "force_constant_n_per_a = 5.0": "force_constant_n_per_a = 11.0",
    "resistance_ohm = 0.7\n": "resistance_ohm = 0.95\n",
    "resistance_min_ohm = 0.6": "resistance_min_ohm = 0.85",
    "resistance_max_ohm = 0.9": "resistance_max_ohm = 1.1",
    "inductance_mh = 1.0": "inductance_mh = 1.6",
}


def write_new_pump_type(folder: Path) -> Path:
    """Write the new pump type's variant file (``p-edc-newtype.toml``) into ``folder``; returns its path."""
    text = (REPO / "configs" / "p-edc-default.toml").read_text(encoding="utf-8")
    for old, new in NEW_PUMP_TYPE_CHANGES.items():
        assert old in text, old  # the default file changed: update the replacements
        text = text.replace(old, new)
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / "p-edc-newtype.toml"
    path.write_text(text, encoding="utf-8")
    return path
