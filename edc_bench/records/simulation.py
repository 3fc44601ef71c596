"""What a test's record says of the simulated rig it ran on: the record's ``simulation`` section, as a model.

The rig's ground truth (the valve as simulated, its coil, the link's timing, the firmware's counters), for the
studies and for a person checking a verdict against the physics. The bench's verdict never reads it; the record
only asks whether it is there (:attr:`edc_bench.records.schema.Record.simulated_rig`).

Two rigs write it: the rig simulated in the bench's process, in simulated time (every field but
``rig_process``: :func:`edc_bench.bench.run_simulated_test`), and the rig process a real-time test talks to over
a socket (``rig_process`` alone: the bench knows only what it started the process with, and what the process said
of its serving gaps).
A field of the section (or of ``rig_process``) that a rig does not give is left out of record.json, not written as
null, so each rig's section reads as it always did.
"""

from __future__ import annotations

from typing import Any

from pydantic import SerializerFunctionWrapHandler, model_serializer

from edc_bench.section import Section


class _WithoutAbsent(Section):
    """A section whose absent fields (None) are left out of record.json."""

    @model_serializer(mode="wrap")
    def _without_absent(self, handler: SerializerFunctionWrapHandler) -> dict[str, Any]:
        return {key: value for key, value in handler(self).items() if value is not None}


class SimulatedValve(Section):
    """The valve as simulated: its spec's label and wear, and the scales they give the friction and damping."""

    label: str = ""
    clearance_mm: float | None = None
    roughness: float | None = None
    friction_scale: float | None = None
    damping_scale: float | None = None


class SimulatedCoil(Section):
    """The simulated coil: its resistance at 20 degC, and its temperature and resistance at the test's start and end."""

    resistance_20c_ohm: float | None = None
    temp_start_c: float | None = None
    temp_end_c: float | None = None
    resistance_start_ohm: float | None = None
    resistance_end_ohm: float | None = None


class RigCounters(Section):
    """What the rig's firmware counted: commands accepted, and refused for a bad CRC or mode; watchdog trips."""

    accepted: int = 0
    bad_crc: int = 0
    bad_mode: int = 0
    watchdog_trips: int = 0


class RigProcessSummary(_WithoutAbsent):
    """The simulated rig process of a real-time test: what it was started with, and its longest serving gap.

    Attributes
    ----------
    valve, adapter, firmware, sensor_drift, rack_fault, sensor_fault : str
        As given on the command line (``--valve``, ``--adapter``, ``--firmware``, ``--rig-drift``'s spec,
        ``--rack-fault``'s and ``--sensor-fault``'s).
    seed : int
        The rig's noise seed.
    worst_gap_ms : float or None
        The longest time the process went without serving (ms), as it said when it stopped; None if it did not.
    """

    valve: str = ""
    seed: int | None = None
    adapter: str = ""
    firmware: str = ""
    worst_gap_ms: float | None = None
    sensor_drift: str | None = None
    rack_fault: str | None = None
    sensor_fault: str | None = None


class SimulationSummary(_WithoutAbsent):
    """The record's ``simulation`` section: the rig simulated in process, or the rig process (``rig_process``)."""

    valve: SimulatedValve | None = None
    coil: SimulatedCoil | None = None
    seed: int | None = None
    stiction: bool | None = None
    sensor_noise: bool | None = None
    firmware: str | None = None
    # the simulator's own dataclasses as fields (SensorDrift, only where the sensors drifted; AdapterModel): the
    # records are read where the simulator is not (a report on another machine), so they are not declared again
    sensor_drift: dict[str, float] | None = None
    adapter: dict[str, float | str] | None = None
    faulty_by_physics: bool | None = None
    resisting_force_n: float | None = None
    coulomb_friction_n: float | None = None
    damping_n_s_per_mm: float | None = None
    rig_counters: RigCounters | None = None
    rig_process: RigProcessSummary | None = None
    # the pump's faulty rack or rack-travel sensor (sim.pump_faults' RackFault and SensorFault, only where faulty)
    rack_fault: dict[str, float] | None = None
    sensor_fault: dict[str, float] | None = None
