"""The simulated rig on a python-can bus, stepped by the caller's clock.

No threads: the bench's simulated clock calls :meth:`InProcessRig.service`
after each send and :meth:`InProcessRig.advance_to` to let time pass, so a
run is deterministic and as fast as the computation allows.
"""

from __future__ import annotations

import can

from edc_bench.sim.rig import SimulatedRig
from firmware_proto.firmware import Frame


class InProcessRig:
    """Connects a :class:`SimulatedRig` to a python-can bus.

    Parameters
    ----------
    bus : can.BusABC
        The rig's end of the bus (a :func:`~edc_bench.sim.lockstep_bus.lockstep_pair` end, or a ``virtual`` bus on the same
        channel as the bench's). Create it with ``preserve_timestamps=True``
        (virtual) so frame timestamps are simulated time.
    rig : SimulatedRig
        The rig.
    """

    def __init__(self, bus: can.BusABC, rig: SimulatedRig) -> None:
        self.bus = bus
        self.rig = rig

    def _send(self, frames: list[Frame], t_s: float) -> None:
        for can_id, data in frames:
            self.bus.send(can.Message(arbitration_id=can_id, data=data, is_extended_id=False, timestamp=t_s))

    def service(self, now_s: float) -> None:
        """Deliver every frame waiting on the bus at ``now_s`` and send the replies."""
        while True:
            msg = self.bus.recv(timeout=0.0)
            if msg is None:
                return
            if msg.is_extended_id or msg.is_remote_frame or msg.is_error_frame:
                continue
            self._send(self.rig.receive(msg.arbitration_id, msg.data, now_s), now_s)

    def advance_to(self, t_s: float) -> None:
        """Let simulated time pass to ``t_s``, sending what the rig sends meanwhile."""
        for can_id, data in self.rig.advance_to(t_s):
            # heartbeats carry the time they were due at, not t_s
            self._send([(can_id, data)], t_s)
