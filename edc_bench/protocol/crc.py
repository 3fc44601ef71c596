"""CRC-8/SAE-J1850 (poly 0x1D, init 0xFF, xorout 0xFF, no reflection)."""

from __future__ import annotations

_POLY = 0x1D


def _make_table() -> tuple[int, ...]:
    table = []
    for byte in range(256):
        crc = byte
        for _ in range(8):
            crc = ((crc << 1) ^ _POLY) & 0xFF if crc & 0x80 else (crc << 1) & 0xFF
        table.append(crc)
    return tuple(table)


_TABLE = _make_table()
# Two bytes per lookup: _PAIRS[(a << 8) | b] = _TABLE[_TABLE[a] ^ b]. An ICD frame's CRC then takes
# four lookups and no loop (a quarter of a codec call's time, four times per tick in simulation).
_PAIRS = [_TABLE[_TABLE[a] ^ b] for a in range(256) for b in range(256)]


def crc8_sae_j1850(data: bytes | bytearray | memoryview, initial: int = 0xFF) -> int:
    """Compute CRC-8/SAE-J1850 of ``data``.

    Parameters
    ----------
    data : bytes-like
        Bytes to protect.
    initial : int, optional
        Register value before the first byte (0xFF for the standard CRC).

    Returns
    -------
    int
        The CRC, 0..255 (check value 0x4B for ``b"123456789"``).
    """
    crc = initial
    table = _TABLE
    for byte in data:
        crc = table[crc ^ byte]
    return crc ^ 0xFF


def e2e_crc(data_id: int, payload: bytes | bytearray | memoryview) -> int:
    """CRC of an ICD frame: over ``data_id`` then payload bytes 1..7.

    Parameters
    ----------
    data_id : int
        The message's data id (low byte of its CAN id).
    payload : bytes-like
        The whole 8-byte payload; byte 0 (the CRC itself) is skipped.

    Returns
    -------
    int
        The CRC to place in byte 0.
    """
    if len(payload) == 8:
        pairs = _PAIRS
        crc = pairs[((0xFF ^ data_id) << 8) | payload[1]]
        crc = pairs[((crc ^ payload[2]) << 8) | payload[3]]
        crc = pairs[((crc ^ payload[4]) << 8) | payload[5]]
        crc = pairs[((crc ^ payload[6]) << 8) | payload[7]]
        return crc ^ 0xFF
    table = _TABLE
    crc = table[0xFF ^ data_id]
    for byte in payload[1:8]:
        crc = table[crc ^ byte]
    return crc ^ 0xFF
