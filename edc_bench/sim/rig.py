"""The simulated rig: the firmware prototype over the simulated plant.

:class:`SimulatedRig` is time-explicit and knows no bus: the caller says what
time it is. The in-process runner (lockstep with a simulated clock) and the
real-time slcan server both drive it through :meth:`SimulatedRig.advance_to`
and :meth:`SimulatedRig.receive`.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any
from dataclasses import dataclass, replace

import numpy as np

from edc_bench.config.models import Variant
from edc_bench.errors import ConfigError
from edc_bench.physics.feedforward import FeedforwardParameters, feedforward_truth
from edc_bench.physics.valve import ValveSpec, plant_parameters
from edc_bench.sim.broken_rigs import BrokenFirmware, IcdBreak
from edc_bench.sim.drift import SensorDrift
from edc_bench.sim.plant import DEFAULT_QUANTUM_S, Plant
from edc_bench.sim.pump_faults import FaultySensorReading, RackFault, SensorFault
from edc_bench.sim.sensors import NoisySensor
from firmware_proto.firmware import FirmwareLimits, Frame, RigFirmware

#: The rig firmwares the simulated rig can run.
FIRMWARES = ("python", "c")


class SimulatedRigHardware:
    """The firmware's hardware interface over the plant and sensor models.

    Attributes
    ----------
    supply_v : float
        Supply voltage it reports (settable for fault injection).
    lvdt_disconnected : bool
        If True the LVDT reads NaN (fault injection).
    drift : SensorDrift
        How far the sensors have drifted (:mod:`edc_bench.sim.drift`): none by default.
    sensor_fault : FaultySensorReading or None
        The pump's rack-travel sensor misreading (:mod:`edc_bench.sim.pump_faults`): None for a sound one.
    """

    def __init__(self, plant: Plant, lvdt: NoisySensor, current: NoisySensor, supply_v: float,
                 drift: SensorDrift | None = None, sensor_fault: FaultySensorReading | None = None) -> None:
        self.plant = plant
        self.lvdt = lvdt
        self.current = current
        self.supply_v = supply_v
        self.lvdt_disconnected = False
        self.drift = drift or SensorDrift()
        self.sensor_fault = sensor_fault

    def sample_position_mm(self) -> float:
        """LVDT reading of the true rack position."""
        if self.lvdt_disconnected:
            return math.nan
        d = self.drift
        x_mm = self.plant.x_mm if self.sensor_fault is None else \
            self.sensor_fault.read(self.plant.x_mm, self.plant.time_s)
        return self.lvdt.sample(d.lvdt_gain * x_mm + d.lvdt_offset_mm)

    def sample_current_a(self) -> float:
        """Current sensor reading of the true coil current."""
        d = self.drift
        return self.current.sample(d.current_gain * self.plant.i_a + d.current_offset_a)

    def set_drive_v(self, drive_v: float) -> None:
        """Drive the amplifier."""
        self.plant.set_drive_v(drive_v)

    def supply_voltage_v(self) -> float:
        """Supply voltage."""
        return self.supply_v


def firmware_limits(variant: Variant) -> FirmwareLimits:
    """Firmware limits of a variant's rig section."""
    rig = variant.rig
    return FirmwareLimits(
        drive_limit_v=rig.drive_limit_v,
        over_current_a=rig.over_current_a,
        travel_min_mm=rig.travel_min_mm,
        travel_max_mm=rig.travel_max_mm,
        lvdt_min_mm=-1.0,
        lvdt_max_mm=variant.rack.stroke_mm + 1.0,
        supply_min_v=rig.supply_min_v,
        watchdog_s=rig.watchdog_ms * 1e-3,
        heartbeat_period_s=rig.heartbeat_period_ms * 1e-3,
        boot_s=rig.boot_ms * 1e-3,
    )


@dataclass(frozen=True)
class RigOptions:
    """Knobs of the simulation that are not part of the variant.

    Attributes
    ----------
    stiction : bool
        Breakaway friction above Coulomb friction (default); False makes the
        plant match the identification model.
    sensor_noise : bool
        Sensor noise, quantisation and offsets (default); False gives exact
        readings.
    quantum_s : float
        Plant time quantum.
    breaks : frozenset of IcdBreak
        ICD rules the rig's firmware breaks (:mod:`edc_bench.sim.broken_rigs`): none by default.
    firmware : str
        ``python``: the prototype (firmware_proto/firmware.py); ``c``: the C core (firmware_proto/c), built on
        first use into the user's cache (:func:`firmware_proto.c_firmware.load_library`).
    drift : SensorDrift
        The sensors' drift (``--rig-drift``, :mod:`edc_bench.sim.drift`): none by default. It is on top of the
        variant's sensor model, and stays when ``sensor_noise`` is off.
    rack_fault : RackFault
        The pump's control rack binding or dragging (``--rack-fault``, :mod:`edc_bench.sim.pump_faults`): none by
        default.
    sensor_fault : SensorFault
        The pump's rack-travel sensor misreading (``--sensor-fault``): none by default. Like ``drift``, it stays
        when ``sensor_noise`` is off.
    """

    stiction: bool = True
    sensor_noise: bool = True
    quantum_s: float = DEFAULT_QUANTUM_S
    breaks: frozenset[IcdBreak] = frozenset()
    firmware: str = "python"
    drift: SensorDrift = SensorDrift()
    rack_fault: RackFault = RackFault()
    sensor_fault: SensorFault = SensorFault()


class SimulatedRig:
    """A whole simulated rig: plant, sensors, amplifier and firmware.

    Parameters
    ----------
    variant : Variant
        Pump variant.
    valve : ValveSpec
        The valve fitted.
    seed : int, optional
        Seed of the sensor noise; same seed, same run.
    options : RigOptions, optional
        Simulation knobs.
    """

    def __init__(self, variant: Variant, valve: ValveSpec, seed: int = 0,
                 options: RigOptions | None = None) -> None:
        self.variant = variant
        self.valve = valve
        self.seed = seed
        self.options = options or RigOptions()
        #: the valve's own physics in this pump (what the bench's truth is), and the plant with the pump's rack
        self.valve_params = plant_parameters(variant, valve, stiction=self.options.stiction)
        self.plant_params = self.options.rack_fault.applied(
            self.valve_params, variant.valve.stiction_ratio if self.options.stiction else 1.0)
        self.plant = Plant(self.plant_params, quantum_s=self.options.quantum_s)
        rng = np.random.default_rng(seed)
        lvdt_model, current_model = variant.sensors.lvdt, variant.sensors.current
        if not self.options.sensor_noise:
            lvdt_model = lvdt_model.model_copy(update={"noise_sd": 0.0, "offset": 0.0, "resolution": 1e-9})
            current_model = current_model.model_copy(update={"noise_sd": 0.0, "offset": 0.0, "resolution": 1e-9})
        self.hardware = SimulatedRigHardware(
            self.plant,
            NoisySensor(lvdt_model, rng.spawn(1)[0]),
            NoisySensor(current_model, rng.spawn(1)[0]),
            variant.rig.supply_voltage_v,
            self.options.drift,
            None if self.options.sensor_fault.none else
            FaultySensorReading(self.options.sensor_fault, variant.rack.stroke_mm, rng.spawn(1)[0]),
        )
        self._quanta_per_s = 1.0 / self.options.quantum_s
        if self.options.firmware not in FIRMWARES:
            raise ConfigError(f"firmware {self.options.firmware!r}: one of {', '.join(FIRMWARES)}")
        if self.options.firmware == "c":
            if self.options.breaks:
                raise ConfigError("the ICD breaks are built on the Python firmware: leave out --firmware c or --break")
            from firmware_proto.c_firmware import CFirmwareMissing, CRigFirmware  # ctypes only where used

            try:
                self.firmware: Any = CRigFirmware(self.hardware, firmware_limits(variant), start_s=0.0)
            except CFirmwareMissing as exc:
                raise ConfigError(str(exc)) from None
        elif self.options.breaks:
            self.firmware = BrokenFirmware(
                self.hardware, firmware_limits(variant), 0.0, self.options.breaks,
                let_time_pass=lambda dt_s: self.plant.advance(int(round(dt_s * self._quanta_per_s))))
        else:
            self.firmware = RigFirmware(self.hardware, firmware_limits(variant), start_s=0.0)
        self._scheduled: list[tuple[float, Callable[[SimulatedRig], list[Frame] | None]]] = []
        self._reached_s = -math.inf  # latest time advance_to has completed

    def schedule(self, at_s: float, action: Callable[[SimulatedRig], list[Frame] | None]) -> None:
        """Run ``action(rig)`` once simulated time reaches ``at_s`` (fault injection); frames it returns are sent."""
        self._scheduled.append((at_s, action))
        self._scheduled.sort(key=lambda item: item[0])

    @property
    def truth(self) -> FeedforwardParameters:
        """True feedforward parameters of this rig's valve with the reference coil (the variant's nominal at
        20 degC), as the bench reports them: the valve's own, without a faulty rack's friction."""
        return feedforward_truth(replace(self.valve_params, resistance_ohm=self.variant.coil.resistance_ohm))

    @property
    def truth_volt(self) -> FeedforwardParameters:
        """True feedforward parameters in volts with this rig's coil as it is now (warmed by the test): the
        valve's own."""
        return feedforward_truth(replace(self.valve_params, resistance_ohm=self.plant.resistance_ohm))

    @property
    def time_s(self) -> float:
        """Simulated time the plant has reached."""
        return self.plant.time_s

    def _advance_plant_to(self, t_s: float) -> None:
        target = int(round(t_s * self._quanta_per_s))
        self.plant.advance(target - self.plant.elapsed_quanta)

    def advance_to(self, t_s: float) -> list[Frame]:
        """Let time pass up to ``t_s``, running firmware timers on the way.

        Returns
        -------
        list of (int, bytes)
            Frames the rig sent meanwhile (heartbeats), in order.
        """
        if t_s <= self._reached_s and not (self._scheduled and self._scheduled[0][0] <= t_s):
            # already there (the bench's clock advanced us; now a frame arrives at the same time):
            # every timer due by then has run, and anything set since lies in the future
            return []
        out: list[Frame] = []
        firmware = self.firmware
        while self._scheduled and self._scheduled[0][0] <= t_s:
            at_s, action = self._scheduled.pop(0)
            self._advance_plant_to(max(at_s, self.plant.time_s))
            out.extend(action(self) or [])
        while True:
            due = firmware.next_deadline_s()
            if due > t_s:
                break
            self._advance_plant_to(due)
            out.extend(firmware.on_time(due))
        self._advance_plant_to(t_s)
        self._reached_s = max(self._reached_s, t_s)
        return out

    def receive(self, can_id: int, data: bytes | bytearray, t_s: float) -> list[Frame]:
        """Deliver a frame at ``t_s`` (time is advanced to ``t_s`` first).

        Returns
        -------
        list of (int, bytes)
            Frames the rig sent, timers first, then the reply.
        """
        out = self.advance_to(t_s)
        out.extend(self.firmware.on_frame(can_id, data, t_s))
        return out
