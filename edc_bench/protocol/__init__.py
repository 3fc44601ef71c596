"""The rig ICD as pure code: the DBC, CRC, DBC-compiled layouts, typed frames, errors.

The protocol owns the ICD: ``icd_v1.dbc`` in this package is its single source
of truth (:func:`dbc_path`). The package needs nothing from edc-bench but
:class:`edc_bench.errors.EdcBenchError`, the root of its errors, so the rig
firmware prototype (``firmware_proto``) builds on it alone.
"""

from edc_bench.protocol.crc import crc8_sae_j1850, e2e_crc
from edc_bench.protocol.errors import E2EError, ProtocolError
from edc_bench.protocol.icd import (
    BENCH_CMD_ID,
    DBC_FILENAME,
    RIG_FEEDBACK_ID,
    RIG_HEARTBEAT_ID,
    BenchCmd,
    FaultCode,
    Icd,
    Mode,
    RigFeedback,
    RigHeartbeat,
    RigState,
    dbc_path,
    default_icd,
)

__all__ = [
    "BENCH_CMD_ID", "DBC_FILENAME", "RIG_FEEDBACK_ID", "RIG_HEARTBEAT_ID", "BenchCmd", "E2EError",
    "FaultCode", "Icd", "Mode", "ProtocolError", "RigFeedback", "RigHeartbeat", "RigState",
    "crc8_sae_j1850", "dbc_path", "default_icd", "e2e_crc",
]
