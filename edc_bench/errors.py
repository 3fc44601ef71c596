"""Errors raised by edc-bench.

Every error the project raises on purpose derives from :class:`EdcBenchError`,
so the CLI can turn it into one clear line instead of a traceback::

    EdcBenchError
     +-- ConfigError (ValueError)        a variant file or a valve spec is wrong
     +-- ProtocolError (ValueError)      a frame cannot be encoded or decoded   [edc_bench.protocol]
     |    +-- E2EError                   CRC of a received frame does not match [edc_bench.protocol]
     +-- RigError (RuntimeError)         the rig or its connection misbehaved
     +-- RecordNotWrittenError (OSError) a measured test's record could not be written (a full disk)

``ProtocolError`` and ``E2EError`` belong to the rig protocol and are defined
in :mod:`edc_bench.protocol.errors` (import them from :mod:`edc_bench.protocol`),
so the protocol, and the firmware prototype built on it, need nothing from
edc-bench but this root class.
"""

from __future__ import annotations


class EdcBenchError(Exception):
    """Root of all errors raised on purpose by edc-bench."""


class ConfigError(EdcBenchError, ValueError):
    """A configuration (variant file, valve spec, CLI value) is invalid."""


class RigError(EdcBenchError, RuntimeError):
    """The rig, or the connection to it, did not behave as the ICD requires."""


class RecordNotWrittenError(EdcBenchError, OSError):
    """A test was measured, but its record could not be written (a full disk, a folder gone); or what a command
    makes (a baseline, a variant's gains) could not be written for a full disk. Exit code 74."""


def disk_full(exc: OSError) -> bool:
    """Whether ``exc`` says there is no room: the disk is full (ENOSPC) or the user's quota used up (EDQUOT)."""
    import errno

    return exc.errno in (errno.ENOSPC, errno.EDQUOT)
