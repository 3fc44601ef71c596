"""Errors raised by edc-bench.

Every error the project raises on purpose derives from :class:`EdcBenchError`,
so the CLI can turn it into one clear line instead of a traceback::

    EdcBenchError
     +-- ConfigError (ValueError)        a variant file or a valve spec is wrong
     +-- ProtocolError (ValueError)      a frame cannot be encoded or decoded
     |    +-- E2EError                   CRC of a received frame does not match
     +-- RigError (RuntimeError)         the rig or its connection misbehaved
"""

from __future__ import annotations


class EdcBenchError(Exception):
    """Root of all errors raised on purpose by edc-bench."""


class ConfigError(EdcBenchError, ValueError):
    """A configuration (variant file, valve spec, CLI value) is invalid."""


class ProtocolError(EdcBenchError, ValueError):
    """A frame cannot be encoded or decoded according to the ICD."""


class E2EError(ProtocolError):
    """A received frame failed its end-to-end (CRC) check."""


class RigError(EdcBenchError, RuntimeError):
    """The rig, or the connection to it, did not behave as the ICD requires."""
