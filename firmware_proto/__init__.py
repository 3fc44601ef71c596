"""The rig side of the edc-bench ICD: the DBC (single source of truth) and the
rig firmware prototype.

The DBC ships inside this package so that it is found the same way from a
source checkout and from a non-editable install.
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path

DBC_FILENAME = "icd_v1.dbc"


def dbc_path() -> Path:
    """Return the path of the ICD v1 DBC file.

    Returns
    -------
    pathlib.Path
        Path of ``icd_v1.dbc`` inside the installed ``firmware_proto`` package.
    """
    return Path(str(resources.files(__name__).joinpath(DBC_FILENAME)))
