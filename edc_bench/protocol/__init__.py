"""The rig ICD as pure code: CRC, DBC-compiled layouts, typed frames."""

from edc_bench.protocol.crc import crc8_sae_j1850, e2e_crc
from edc_bench.protocol.icd import (
    BENCH_CMD_ID,
    RIG_FEEDBACK_ID,
    RIG_HEARTBEAT_ID,
    BenchCmd,
    FaultCode,
    Icd,
    Mode,
    RigFeedback,
    RigHeartbeat,
    RigState,
    default_icd,
)

__all__ = [
    "BENCH_CMD_ID", "RIG_FEEDBACK_ID", "RIG_HEARTBEAT_ID", "BenchCmd", "FaultCode", "Icd", "Mode",
    "RigFeedback", "RigHeartbeat", "RigState", "crc8_sae_j1850", "default_icd", "e2e_crc",
]
