"""The rig side of the edc-bench ICD: the rig firmware prototype.

The ICD itself (the DBC, single source of truth) belongs to the protocol,
:mod:`edc_bench.protocol`; ``icd_v1.dbc`` beside this file in a source checkout
is a symlink to ``edc_bench/protocol/icd_v1.dbc``, for firmware authors.
:func:`dbc_path` is the protocol's, re-exported here.
"""

from __future__ import annotations

from edc_bench.protocol import DBC_FILENAME, dbc_path

__all__ = ["DBC_FILENAME", "dbc_path"]
