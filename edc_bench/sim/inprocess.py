"""The simulated rig on a python-can bus, stepped by the caller's clock.

No threads: the bench's simulated clock calls :meth:`InProcessRig.service`
after each send and :meth:`InProcessRig.advance_to` to let time pass, so a
run is deterministic and as fast as the computation allows.

With an :class:`~edc_bench.sim.adapter.AdapterModel` between bench and rig,
frames take their time in both directions: a command reaches the rig when
the adapter delivers it, and the reply reaches the bench's bus when the
adapter delivers that, in simulated time, still deterministically.
"""

from __future__ import annotations

import math
from collections import deque
from typing import TYPE_CHECKING

import numpy as np

from edc_bench.canlib import can

from edc_bench.sim.adapter import AdapterModel
from edc_bench.sim.rig import SimulatedRig
from firmware_proto.firmware import Frame

if TYPE_CHECKING:
    from can import BusABC


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
    adapter : AdapterModel, optional
        The adapter's timing between bench and rig; instant by default.
    seed : int, optional
        Seed of the adapter's jitter.
    """

    def __init__(self, bus: BusABC, rig: SimulatedRig, adapter: AdapterModel | None = None,
                 seed: int = 0) -> None:
        self.bus = bus
        self.rig = rig
        self.adapter = adapter or AdapterModel()
        self._rng = np.random.default_rng([seed, 0xADA])
        self._to_rig: deque[tuple[float, int, bytes]] = deque()
        self._to_bench: deque[tuple[float, int, bytes]] = deque()
        self._last_to_rig = self._last_to_bench = -math.inf

    def _send(self, frames: list[Frame], t_s: float) -> None:
        if self.adapter.is_instant:
            for can_id, data in frames:
                self.bus.send(can.Message(arbitration_id=can_id, data=data, is_extended_id=False, timestamp=t_s))
            return
        for can_id, data in frames:
            self._last_to_bench = self.adapter.delivery_s(t_s, self._rng, self._last_to_bench)
            self._to_bench.append((self._last_to_bench, can_id, data))

    def service(self, now_s: float) -> None:
        """Take every frame the bench has sent by ``now_s``; deliver what is due, both ways."""
        while True:
            msg = self.bus.recv(timeout=0.0)
            if msg is None:
                break
            if msg.is_extended_id or msg.is_remote_frame or msg.is_error_frame:
                continue
            if self.adapter.is_instant:
                self._send(self.rig.receive(msg.arbitration_id, msg.data, now_s), now_s)
            else:
                self._last_to_rig = self.adapter.delivery_s(now_s, self._rng, self._last_to_rig)
                self._to_rig.append((self._last_to_rig, msg.arbitration_id, bytes(msg.data)))
        if not self.adapter.is_instant:
            self._deliver_until(now_s)

    def advance_to(self, t_s: float) -> None:
        """Let simulated time pass to ``t_s``, sending what the rig sends meanwhile."""
        if not self.adapter.is_instant:
            self._deliver_until(t_s)
            return
        for can_id, data in self.rig.advance_to(t_s):
            # heartbeats carry the time they were due at, not t_s
            self._send([(can_id, data)], t_s)

    def _deliver_until(self, t_s: float) -> None:
        """Commands reach the rig in order as the adapter delivers them; the bench gets what is due by ``t_s``."""
        while self._to_rig and self._to_rig[0][0] <= t_s:
            at_s, can_id, data = self._to_rig.popleft()
            self._send(self.rig.advance_to(at_s), at_s)
            self._send(self.rig.receive(can_id, data, at_s), at_s)
        self._send(self.rig.advance_to(t_s), t_s)
        while self._to_bench and self._to_bench[0][0] <= t_s:
            at_s, can_id, data = self._to_bench.popleft()
            self.bus.send(can.Message(arbitration_id=can_id, data=data, is_extended_id=False, timestamp=at_s))
