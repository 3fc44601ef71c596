"""The device side of the slcan (LAWICEL) ASCII protocol, pure.

Enough of it for any slcan host, python-can's ``slcan`` interface included:
open/close, bitrate, version and serial number, status flags, standard and
extended data frames, remote frames. Unknown commands answer BEL, as devices do.

Lines are parsed strictly, since whatever the device takes for a frame goes
on the bus (to the rig, and to every other host). Frame lines are read by
:func:`edc_bench.protocol.slcan.parse_frame_line`, the rules the bench reads
an adapter's lines by (exact hex digits, exact lengths, DLC 0-8, ids in
range, nothing after), so both ends of the link hold to the same rules.
Commands without an argument take none. Anything else, and any line longer
than :data:`MAX_LINE`, is answered BEL and counted.
"""

from __future__ import annotations

from collections.abc import Callable

from edc_bench.protocol.slcan import MAX_LINE, SlcanFrame, format_frame_line, is_hex, parse_frame_line

__all__ = ["ERROR", "MAX_LINE", "OK", "STATUS_DATA_OVERRUN", "SlcanDevice", "SlcanFrame"]

OK = b"\r"
ERROR = b"\a"
#: ``F`` status flag bit 3: frames were lost because the host did not take them (data overrun)
STATUS_DATA_OVERRUN = 0x08

_FRAME_KINDS = frozenset(b"tTrR")
#: commands without an argument and their answers
_PLAIN_COMMANDS = {b"O": OK, b"L": OK, b"C": OK, b"V": b"V1013\r", b"v": b"v1013\r", b"N": b"NEDC1\r"}
#: register-level bit timing, acceptance filter: accepted (argument checked), not modelled
_SETTINGS = {ord("s"): 4, ord("M"): 8, ord("m"): 8}


class SlcanDevice:
    """Parses host commands and formats received frames.

    Attributes
    ----------
    is_open : bool
        Channel opened with ``O`` (or ``L``) and not closed since.
    listen_only : bool
        Opened with ``L``: the host may not transmit.
    bitrate_code : str
        Last ``S`` code set by the host.
    errors : int
        Lines answered BEL: malformed, unknown, too long, or a frame while not open.
    overrun : bool
        Frames for the host were lost since it last read the status flags (``F``); set by the server.
    """

    def __init__(self) -> None:
        self.is_open = False
        self.listen_only = False
        self.bitrate_code = "6"
        self.errors = 0
        self.overrun = False
        self._buffer = bytearray()
        self._discarding = False  # inside a line that grew too long: dropped up to its CR

    def feed(self, data: bytes,
             admit: Callable[[SlcanFrame], bool] | None = None) -> tuple[list[SlcanFrame], bytes]:
        """Process bytes from the host.

        Parameters
        ----------
        data : bytes
            What the host sent, any chunk of its stream.
        admit : callable, optional
            Asked about each well-formed frame while the channel is open; a
            frame it refuses is answered BEL instead of ``z``/``Z`` and not
            returned.

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
                if len(self._buffer) > MAX_LINE and not self._discarding:
                    reply += self._error()  # once per overlong line, however it arrives
                    self._discarding = True
                if self._discarding:
                    self._buffer.clear()
                break
            line = bytes(self._buffer[:end])
            del self._buffer[: end + 1]
            if self._discarding:
                self._discarding = False  # the rest of the overlong line
                continue
            if len(line) > MAX_LINE:
                reply += self._error()
                continue
            answer, frame = self._command(line.lstrip(b"\n"))  # LF after CR: hosts ending lines CR LF
            if frame is not None and admit is not None and not admit(frame):
                answer, frame = ERROR, None
            reply += answer
            if frame is not None:
                frames.append(frame)
        return frames, bytes(reply)

    def _error(self) -> bytes:
        self.errors += 1
        return ERROR

    def _command(self, line: bytes) -> tuple[bytes, SlcanFrame | None]:
        if not line:
            return OK, None
        op = line[0]
        if op in _FRAME_KINDS:
            frame = parse_frame_line(line)
            if frame is None or not self.is_open or self.listen_only:
                return self._error(), None
            return (b"Z\r" if frame.extended else b"z\r"), frame
        if line in _PLAIN_COMMANDS:
            self._set_channel(line)
            return _PLAIN_COMMANDS[line], None
        if line == b"F":
            flags, self.overrun = STATUS_DATA_OVERRUN if self.overrun else 0, False  # reading clears them
            return f"F{flags:02X}\r".encode("ascii"), None
        if op == ord("S") and len(line) == 2 and ord("0") <= line[1] <= ord("8"):
            self.bitrate_code = chr(line[1])
            return OK, None
        if op == ord("Z") and line[1:] in (b"0", b"1"):
            return OK, None
        if op in _SETTINGS and len(line) == 1 + _SETTINGS[op] and is_hex(line[1:]):
            return OK, None
        return self._error(), None

    def _set_channel(self, line: bytes) -> None:
        """Open, listen-only or close, for the commands that change the channel."""
        if line == b"O":
            self.is_open, self.listen_only = True, False
        elif line == b"L":
            self.is_open, self.listen_only = True, True
        elif line == b"C":
            self.is_open = False

    @staticmethod
    def format_frame(can_id: int, data: bytes, extended: bool = False) -> bytes:
        """The line a device sends to the host for a received data frame."""
        return format_frame_line(SlcanFrame(can_id, bytes(data), extended))
