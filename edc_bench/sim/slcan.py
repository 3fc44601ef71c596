"""The device side of the slcan (LAWICEL) ASCII protocol, pure.

Enough of it for any slcan host, python-can's ``slcan`` interface included:
open/close, bitrate, version and serial number, status flags, standard and
extended data frames, remote frames. Unknown commands answer BEL, as devices do.
"""

from __future__ import annotations

from dataclasses import dataclass

OK = b"\r"
ERROR = b"\a"
MAX_LINE = 64


@dataclass(frozen=True)
class SlcanFrame:
    """A CAN frame sent by the host."""

    can_id: int
    data: bytes
    extended: bool = False
    remote: bool = False


class SlcanDevice:
    """Parses host commands and formats received frames.

    Attributes
    ----------
    is_open : bool
        Channel opened with ``O`` (or ``L``) and not closed since.
    bitrate_code : str
        Last ``S`` code set by the host.
    """

    def __init__(self) -> None:
        self.is_open = False
        self.listen_only = False
        self.bitrate_code = "6"
        self._buffer = bytearray()
        self.errors = 0

    def feed(self, data: bytes) -> tuple[list[SlcanFrame], bytes]:
        """Process bytes from the host.

        Returns
        -------
        frames : list of SlcanFrame
            Frames the host transmitted (only while the channel is open).
        reply : bytes
            What the device answers, to be written back to the host.
        """
        self._buffer.extend(data)
        frames: list[SlcanFrame] = []
        reply = bytearray()
        while True:
            end = self._buffer.find(b"\r")
            if end < 0:
                if len(self._buffer) > MAX_LINE:  # garbage without a terminator
                    self._buffer.clear()
                    self.errors += 1
                    reply += ERROR
                break
            line = bytes(self._buffer[:end]).lstrip(b"\n")
            del self._buffer[: end + 1]
            answer, frame = self._command(line)
            reply += answer
            if frame is not None:
                frames.append(frame)
        return frames, bytes(reply)

    def _command(self, line: bytes) -> tuple[bytes, SlcanFrame | None]:
        if not line:
            return OK, None
        op, arg = chr(line[0]), line[1:].decode("ascii", "replace")
        if op in "tTrR":
            frame = self._parse_frame(op, arg)
            if frame is None or not self.is_open or self.listen_only:
                self.errors += 1
                return ERROR, None
            return (b"z\r" if op in "tr" else b"Z\r"), frame
        if op == "O":
            self.is_open, self.listen_only = True, False
        elif op == "L":
            self.is_open, self.listen_only = True, True
        elif op == "C":
            self.is_open = False
        elif op == "S" and len(arg) == 1 and arg in "012345678":
            self.bitrate_code = arg
        elif op in "sZMm":
            pass  # register-level bit timing, timestamps, acceptance filter: accepted, not modelled
        elif op == "V":
            return b"V1013\r", None
        elif op == "v":
            return b"v1013\r", None
        elif op == "N":
            return b"NEDC1\r", None
        elif op == "F":
            return b"F00\r", None
        else:
            self.errors += 1
            return ERROR, None
        return OK, None

    @staticmethod
    def _parse_frame(op: str, arg: str) -> SlcanFrame | None:
        id_len = 3 if op in "tr" else 8
        try:
            can_id = int(arg[:id_len], 16)
            dlc = int(arg[id_len])
            if len(arg) < id_len + 1 or dlc > 8:
                return None
            if op in "rR":
                return SlcanFrame(can_id, bytes(dlc), op == "R", True)
            hex_data = arg[id_len + 1 : id_len + 1 + 2 * dlc]
            if len(hex_data) != 2 * dlc:
                return None
            return SlcanFrame(can_id, bytes.fromhex(hex_data), op == "T")
        except (ValueError, IndexError):
            return None

    @staticmethod
    def format_frame(can_id: int, data: bytes, extended: bool = False) -> bytes:
        """The line a device sends to the host for a received frame."""
        head = f"T{can_id:08X}" if extended else f"t{can_id:03X}"
        return f"{head}{len(data)}{data.hex().upper()}\r".encode("ascii")
