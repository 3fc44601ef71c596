"""A pair of python-can buses joined back to back, for lockstep simulation.

python-can's ``virtual`` interface deep-copies every message and passes it
through a locked queue per receiver: about 20 % of a simulated bench test
went there. In lockstep nothing is concurrent and no one changes a message
after sending it (the bench and the rig build a new one per frame), so a
:class:`LockstepBus` hands the sent message object to its peer's inbox as
it is. It is a full :class:`can.BusABC`, so the bench loop, fault
injection and recording see the same bus interface as on a real rig.
"""

from __future__ import annotations

from collections import deque

from edc_bench.canlib import can


class LockstepBus(can.BusABC):
    """One end of a back-to-back pair; make pairs with :func:`lockstep_pair`.

    Receive filters are not applied (``recv`` is the inbox, unfiltered): the
    bench and the rig read every frame anyway.
    """

    def __init__(self, channel: str = "lockstep", **kwargs: object) -> None:
        self._inbox: deque[can.Message] = deque()
        self.peer: LockstepBus | None = None
        self.channel_info = f"lockstep {channel}"
        super().__init__(channel=channel, **kwargs)

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        """Put ``msg`` (not a copy) into the peer's inbox."""
        if self._is_shutdown:
            raise can.CanOperationError("the lockstep bus is shut down")
        if self.peer is None:
            raise can.CanOperationError("the lockstep bus has no peer: make buses with lockstep_pair()")
        self.peer._inbox.append(msg)

    def recv(self, timeout: float | None = None) -> can.Message | None:
        """The oldest frame waiting, or None at once (nothing else can send meanwhile)."""
        inbox = self._inbox
        return inbox.popleft() if inbox else None

    def _recv_internal(self, timeout: float | None) -> tuple[can.Message | None, bool]:
        inbox = self._inbox
        return (inbox.popleft() if inbox else None), False

    def shutdown(self) -> None:
        """Close this end; frames still waiting are dropped."""
        self._inbox.clear()
        super().shutdown()


def lockstep_pair(channel: str = "lockstep") -> tuple[LockstepBus, LockstepBus]:
    """Two buses joined back to back: what one sends, the other receives.

    Returns
    -------
    (LockstepBus, LockstepBus)
        The bench's end and the rig's end.
    """
    a, b = LockstepBus(channel), LockstepBus(channel)
    a.peer, b.peer = b, a
    return a, b
