"""Fault injection for tests: a python-can bus wrapper and rig-side faults.

:class:`FaultyBus` wraps the bench's bus and, while a rule is active (by the
bench clock's time), drops, delays, corrupts, repeats or reorders frames,
raises python-can errors, or cuts the rig off. :func:`schedule_rig_fault`
makes the simulated rig misbehave at a given time: heartbeat stops, a latched
FAULT, an over-current, a disconnected or stuck LVDT, a rack beyond its
travel, a NaN sample.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass

from edc_bench.canlib import can

from edc_bench.protocol import BENCH_CMD_ID, FaultCode


@dataclass
class Rule:
    """One fault, active from ``start_s`` to ``end_s`` (bench clock).

    Attributes
    ----------
    kind : str
        ``drop`` (frames vanish), ``delay`` (received frames arrive ``delay_s``
        late), ``corrupt`` (received frames get a wrong CRC), ``repeat`` (the
        bench's command is replaced by its previous one: a stale counter),
        ``reorder`` (received frames swapped pairwise), ``error`` (python-can
        raises CanOperationError), ``bus_off`` (every send and receive raises),
        ``cut`` (the rig is unplugged: nothing passes either way).
    direction : str
        ``rx``, ``tx`` or ``both`` (for drop).
    can_id : int or None
        Only frames with this id (None: all).
    """

    kind: str
    start_s: float
    end_s: float = math.inf
    direction: str = "rx"
    can_id: int | None = None
    delay_s: float = 0.005

    def active(self, now_s: float) -> bool:
        return self.start_s <= now_s < self.end_s

    def matches(self, msg: can.Message, direction: str) -> bool:
        return (self.direction in (direction, "both")) and (self.can_id is None or msg.arbitration_id == self.can_id)


class FaultyBus(can.BusABC):
    """A python-can bus that misbehaves on purpose.

    Parameters
    ----------
    inner : can.BusABC
        The real (or virtual) bus.
    now_s : callable
        The bench clock's time (rules are scheduled on it).
    rules : list of Rule
        Faults to apply.
    """

    def __init__(self, inner: can.BusABC, now_s: Callable[[], float], rules: list[Rule]) -> None:
        self.inner = inner
        self.now_s = now_s
        self.rules = rules
        self._last_sent: can.Message | None = None
        self._delayed: deque[tuple[float, can.Message]] = deque()
        self._reorder_held: can.Message | None = None
        self.injected = 0
        super().__init__(channel=getattr(inner, "channel_info", "faulty"))

    def _active(self, kind: str, msg: can.Message | None = None, direction: str = "rx") -> bool:
        now = self.now_s()
        for rule in self.rules:
            if rule.kind == kind and rule.active(now) and (msg is None or rule.matches(msg, direction)):
                return True
        return False

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        if self._active("bus_off") or self._active("error", direction="tx"):
            self.injected += 1
            raise can.CanOperationError("injected: bus off" if self._active("bus_off") else "injected: send failed")
        if self._active("cut") or self._active("drop", msg, "tx"):
            self.injected += 1
            return
        if msg.arbitration_id == BENCH_CMD_ID and self._active("repeat", msg, "tx") and self._last_sent is not None:
            self.injected += 1
            self.inner.send(self._last_sent, timeout)
            return
        self._last_sent = msg
        self.inner.send(msg, timeout)

    def _recv_internal(self, timeout: float | None) -> tuple[can.Message | None, bool]:
        if self._active("bus_off") or self._active("error", direction="rx"):
            self.injected += 1
            raise can.CanOperationError("injected: bus off" if self._active("bus_off") else "injected: receive failed")
        now = self.now_s()
        if self._delayed and self._delayed[0][0] <= now:
            return self._delayed.popleft()[1], False
        while True:
            msg = self.inner.recv(timeout)
            if msg is None:
                if self._reorder_held is not None and not self._active("reorder"):
                    held, self._reorder_held = self._reorder_held, None
                    return held, False
                return None, False
            if self._active("cut") or self._active("drop", msg, "rx"):
                self.injected += 1
                continue
            if self._active("corrupt", msg, "rx"):
                self.injected += 1
                data = bytearray(msg.data)
                data[0] ^= 0xA5
                msg = can.Message(arbitration_id=msg.arbitration_id, data=bytes(data), is_extended_id=False,
                                  timestamp=msg.timestamp)
            if self._active("delay", msg, "rx"):
                self.injected += 1
                delay = next(r.delay_s for r in self.rules if r.kind == "delay" and r.active(now))
                self._delayed.append((now + delay, msg))
                continue
            if self._active("reorder", msg, "rx"):
                if self._reorder_held is None:
                    self._reorder_held = msg
                    continue
                self.injected += 1
                held, self._reorder_held = self._reorder_held, None
                self._delayed.appendleft((now, held))
                return msg, False
            return msg, False

    def shutdown(self) -> None:
        super().shutdown()


# -- rig-side faults --------------------------------------------------------------

RIG_FAULTS = ("heartbeat_stops", "rig_fault", "over_current", "lvdt_disconnected", "lvdt_stuck",
              "travel_limit", "lvdt_out_of_range", "current_nan")


def _apply(rig, fault: str) -> list | None:
    hw = rig.hardware
    if fault == "heartbeat_stops":
        rig.firmware.heartbeat_enabled = False
    elif fault == "rig_fault":
        return rig.firmware.force_fault(FaultCode.SUPPLY_LOW)
    elif fault == "over_current":
        hw.current.stuck_value = 40.0
    elif fault == "lvdt_disconnected":
        hw.lvdt_disconnected = True
    elif fault == "lvdt_stuck":
        hw.lvdt.stuck_value = rig.variant.rack.mid_stroke_mm
    elif fault == "travel_limit":
        hw.lvdt.stuck_value = rig.variant.rig.travel_max_mm + 0.3
    elif fault == "lvdt_out_of_range":
        hw.lvdt.stuck_value = rig.variant.rack.stroke_mm + 5.0
    elif fault == "current_nan":
        hw.current.stuck_value = math.nan
    else:
        raise ValueError(f"unknown rig fault {fault!r}; expected one of {', '.join(RIG_FAULTS)}")
    return None


def schedule_rig_fault(rig, fault: str, at_s: float) -> None:
    """Make the simulated ``rig`` misbehave from its time ``at_s`` on.

    Parameters
    ----------
    rig : SimulatedRig
        The rig.
    fault : str
        One of :data:`RIG_FAULTS`.
    at_s : float
        Rig time (seconds since the rig powered up).
    """
    if fault not in RIG_FAULTS:
        raise ValueError(f"unknown rig fault {fault!r}; expected one of {', '.join(RIG_FAULTS)}")
    rig.schedule(at_s, lambda r: _apply(r, fault))


__all__ = ["RIG_FAULTS", "FaultyBus", "Rule", "schedule_rig_fault"]
