"""slcan (LAWICEL) frame lines, parsed strictly: pure, no bus.

A CAN adapter speaking slcan sends each received frame as one ASCII line,
ended by CR:

========  =====================================  ===========================
line      fields                                 frame
========  =====================================  ===========================
``t``     3 hex id, 1 DLC digit, 2*DLC hex       standard data frame
``T``     8 hex id, 1 DLC digit, 2*DLC hex       extended (29-bit) data frame
``r``     3 hex id, 1 DLC digit                  standard remote frame
``R``     8 hex id, 1 DLC digit                  extended remote frame
========  =====================================  ===========================

A line is a frame only if it is exactly that: hex digits only (no sign,
underscore or space, which Python's ``int(text, 16)`` would let through),
a standard id up to 0x7FF, an extended id up to 0x1FFFFFFF, DLC 0-8 and
nothing after the payload. Anything else is not a frame: a bench that took
a damaged line for a frame could act on a reply nobody sent.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

STANDARD_ID_MAX = 0x7FF
EXTENDED_ID_MAX = 0x1FFFFFFF
#: longer than any classic slcan frame line (``T``, 8 id digits, DLC, 16 data digits): a line beyond is noise
MAX_LINE = 64
_HEX = re.compile(rb"[0-9A-Fa-f]*")
#: per line kind: the whole line's pattern (id, DLC, payload), extended, remote
_KINDS = {
    ord("t"): (re.compile(rb"t([0-9A-Fa-f]{3})([0-8])([0-9A-Fa-f]*)"), False, False),
    ord("T"): (re.compile(rb"T([0-9A-Fa-f]{8})([0-8])([0-9A-Fa-f]*)"), True, False),
    ord("r"): (re.compile(rb"r([0-9A-Fa-f]{3})([0-8])"), False, True),
    ord("R"): (re.compile(rb"R([0-9A-Fa-f]{8})([0-8])"), True, True),
}


@dataclass(frozen=True, slots=True)
class SlcanFrame:
    """A classic CAN frame carried by an slcan line."""

    can_id: int
    data: bytes
    extended: bool = False
    remote: bool = False
    dlc: int | None = None  # a remote frame's DLC (a data frame's is len(data))

    @property
    def length(self) -> int:
        """The frame's DLC."""
        return len(self.data) if self.dlc is None else self.dlc


def is_hex(text: bytes) -> bool:
    """True if ``text`` is hex digits only (no sign, underscore or space)."""
    return _HEX.fullmatch(text) is not None


def parse_frame_line(line: bytes) -> SlcanFrame | None:
    """The frame an slcan line carries, or None if the line is not exactly a valid frame line.

    Parameters
    ----------
    line : bytes
        One line without its CR terminator.

    Returns
    -------
    SlcanFrame or None
        None for anything but a well-formed ``t``/``T``/``r``/``R`` line
        (device replies such as ``z`` or ``V1013`` included).
    """
    if not line or line[0] not in _KINDS:
        return None
    pattern, extended, remote = _KINDS[line[0]]
    match = pattern.fullmatch(line)
    if match is None:
        return None
    can_id, dlc = int(match[1], 16), int(match[2])
    if can_id > (EXTENDED_ID_MAX if extended else STANDARD_ID_MAX):
        return None
    if remote:
        return SlcanFrame(can_id, b"", extended, True, dlc)
    payload = match[3]
    if len(payload) != 2 * dlc:
        return None
    return SlcanFrame(can_id, bytes.fromhex(payload.decode("ascii")), extended, False)


def format_frame_line(frame: SlcanFrame) -> bytes:
    """The slcan line (with its CR) for ``frame``; the inverse of :func:`parse_frame_line`."""
    kind = ("R" if frame.extended else "r") if frame.remote else ("T" if frame.extended else "t")
    head = f"{kind}{frame.can_id:08X}" if frame.extended else f"{kind}{frame.can_id:03X}"
    payload = "" if frame.remote else frame.data.hex().upper()
    return f"{head}{frame.length}{payload}\r".encode("ascii")
