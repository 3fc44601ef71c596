"""Errors of the rig protocol: a frame that cannot be encoded, decoded or trusted.

They derive from :class:`edc_bench.errors.EdcBenchError` like every error the
project raises on purpose, so the CLI reports them in one line.
"""

from __future__ import annotations

from edc_bench.errors import EdcBenchError


class ProtocolError(EdcBenchError, ValueError):
    """A frame cannot be encoded or decoded according to the ICD."""


class E2EError(ProtocolError):
    """A received frame failed its end-to-end (CRC) check."""
