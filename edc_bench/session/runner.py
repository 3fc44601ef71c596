"""One valve of a shift: its test, a MARGINAL's retest, and for each test the record, the report and the history row.

The session's screen shows what this returns; nothing here draws on it. A test runs in the caller's thread (the
app runs it in a worker thread); what a person must know of a failure on the way (a report or the history that
could not be written) comes back as words, never as an exception, so the shift goes on and the record is safe.
"""

from __future__ import annotations

import zlib
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

from edc_bench.config.models import Variant
from edc_bench.records.advice import Cause
from edc_bench.verdict.retest import Decision, decide, retest_wanted

if TYPE_CHECKING:
    from edc_bench.runtime.bus_config import BusSettings
    from edc_bench.verdict.sections import RetestSummary


@dataclass(frozen=True)
class RigChoice:
    """Where the session's tests run.

    Attributes
    ----------
    bus_config : BusSettings or None
        A real rig's bus (python-can settings), or None for the simulated rig (in process, simulated time).
    first_seed : int
        The simulated rig's first noise seed; each test of the session takes the next, so a retest sees new noise.
    rig_drift : SensorDrift or None
        The simulated rig's sensors drifted (``--rig-drift``), what the rig self-check must catch; None: none.
    rack_fault, sensor_fault : RackFault or SensorFault or None
        The simulated pump's rack binds or drags, its rack-travel sensor misreads (``--rack-fault``,
        ``--sensor-fault``), every valve of the session tested in that pump (the rig self-check's reference valve
        is not: it has a pump of its own); None: sound.
    """

    bus_config: BusSettings | None = None
    first_seed: int = 0
    rig_drift: Any = None
    rack_fault: Any = None
    sensor_fault: Any = None

    @property
    def simulated(self) -> bool:
        """The simulated rig."""
        return self.bus_config is None

    def describe(self) -> str:
        """The rig in a few words, for the screen and the shift summary."""
        if self.simulated:
            said = [f"{what}: {fault.spec()}" for what, fault in (("sensors drifted", self.rig_drift),
                                                                   ("rack faulty", self.rack_fault),
                                                                   ("rack-travel sensor faulty", self.sensor_fault))
                    if fault is not None and not fault.none]
            return "simulated rig" + (f" ({'; '.join(said)})" if said else "")
        return f"rig on {self.bus_config.get('interface')} {self.bus_config.get('channel') or ''}".strip()


@dataclass(frozen=True)
class TestDone:
    """One test as the session shows it."""

    result: Any  # the BenchResult
    record_dir: Path | None
    report_pdf: Path | None  # None until :meth:`SessionRunner.draw_reports` has drawn it
    problems: tuple[str, ...]  # what went wrong on the way (record, report, history), in words
    indexed: bool = False  # its history row was written
    escalation: str = ""  # its record's escalation: the same valve INVALID twice, it may be seized ("" if not)

    @property
    def verdict(self) -> str:
        """The test's verdict."""
        return str(self.result.verdict)


@dataclass(frozen=True)
class ValveDone:
    """A valve's tests and what the technician does."""

    valve_id: str
    pump_serial: str
    variant: str
    tests: tuple[TestDone, ...]
    decision: Decision | None  # a retested MARGINAL's

    @property
    def final(self) -> str:
        """The verdict the technician acts on."""
        return str(self.decision.verdict) if self.decision is not None else self.tests[-1].verdict

    @property
    def words(self) -> str:
        """What to do."""
        return self.decision.words if self.decision is not None else self.tests[-1].result.advice.words

    @property
    def escalation(self) -> str:
        """The technician's line when the valve's last test escalates (INVALID twice, both times for a cause the
        valve itself can cause: it may be seized), as its record says; "" if not."""
        return self.tests[-1].escalation if self.final == "INVALID" else ""

    @property
    def cause(self) -> Cause | None:
        """Who the valve's last test points at, when the technician acts on an INVALID (else None)."""
        return self.tests[-1].result.invalid_cause if self.final == "INVALID" else None


def simulated_valve(variant: Variant, valve_id: str) -> Any:
    """The valve the simulated rig holds for ``valve_id``: the spec the id names (``new``, ``worn``,
    ``clearance=0.185``), else a used valve of the variant's population drawn from the id (the same id, the same
    valve)."""
    from edc_bench.errors import ConfigError
    from edc_bench.physics.valve import parse_valve_spec
    from edc_bench.population.valves import draw_population

    try:
        return parse_valve_spec(valve_id, variant)
    except (ConfigError, ValueError):
        return draw_population(variant, 1, zlib.crc32(valve_id.encode("utf-8")))[0]


class SessionRunner:
    """Runs a shift's tests and keeps each one's record, report and history row.

    Parameters
    ----------
    rig : RigChoice
        Where the tests run.
    out_dir : pathlib.Path
        The records folder.
    history_url : str or None
        The history database (None: the station's).
    station, operator : str
        Who and where, for every record.
    report : bool
        Draw each test's report (PDF and PNG) into its record folder (default).
    """

    def __init__(self, rig: RigChoice, out_dir: Path, history_url: str | None, station: str, operator: str,
                 report: bool = True, station_given: str | None = None) -> None:
        self.rig, self.out_dir, self.history_url = rig, Path(out_dir), history_url
        self.station, self.operator, self.report = station, operator, report
        self.station_given = station_given  # --station, which the customer's page prints as given
        self.tests_run = 0

    def run_valve(self, variant: Variant, valve_id: str, pump_serial: str,
                  observer: Callable[[str], Any] | None = None, job_ref: str = "") -> ValveDone:
        """Test a mounted valve; a MARGINAL is tested again at once and the variant's rule decides the pair.

        Parameters
        ----------
        observer : callable, optional
            Called with ``"test"`` or ``"retest"`` before each test; returns the test's
            :class:`~edc_bench.runtime.loop.LoopObserver` (or None).
        job_ref : str, optional
            The job or vehicle reference scanned with the valve, for both tests' records.
        """
        from edc_bench.runtime.signals import stop_requested

        first = self.run_test(variant, valve_id, pump_serial, observer("test") if observer else None,
                              job_ref=job_ref)
        if (first.record_dir is None or stop_requested()  # interrupted: no retest is started
                or not retest_wanted(first.result.verdict, variant.retest)):
            return ValveDone(valve_id, pump_serial, variant.name, (first,), None)
        try:
            second = self.run_test(variant, valve_id, pump_serial, observer("retest") if observer else None,
                                   retest_of=first, job_ref=job_ref)
        except Exception as exc:  # noqa: BLE001 - the first test stands, with its record and report
            why = f"the retest could not run ({type(exc).__name__}: {exc}): check the rig, then scan the valve again"
            return ValveDone(valve_id, pump_serial, variant.name, (replace(first, problems=(*first.problems, why)),),
                             None)
        decision = decide(second.result.verdict, variant.retest, second.result.advice.words)
        return ValveDone(valve_id, pump_serial, variant.name, (first, second), decision)

    def run_test(self, variant: Variant, valve_id: str, pump_serial: str, observer: Any = None,
                 retest_of: TestDone | None = None, job_ref: str = "") -> TestDone:
        """One test: run it, write its record, add it to the history (its report is drawn by :meth:`draw_reports`)."""
        from edc_bench.records.writer import CAN_LOG_FILE, new_record_dir

        folder: list[Path] = []

        def stream_target(started: str) -> Path:  # the record folder exists from the first frame on
            folder.append(new_record_dir(self.out_dir, valve_id, variant.name, started))
            return folder[0] / CAN_LOG_FILE

        from edc_bench.bench import BenchOptions
        from edc_bench.records.schema import Identity
        from edc_bench.runtime.bus_config import rig_on_this_pc
        from edc_bench.station_settings import station_identity
        from edc_bench.verdict.judgement import default_calibrate_command

        shop = station_identity()
        options = BenchOptions(
            valve_id=valve_id, identity=Identity(pump_serial=pump_serial, station=self.station,
                                                 station_shown=shop.for_customers(self.station_given),
                                                 operator=self.operator, shop=shop.shop,
                                                 shop_address=shop.shop_address, job_ref=job_ref),
            calibrate_command=default_calibrate_command(variant, ["--valve", "new"] if self.rig.simulated else []),
            stream_can_log=stream_target, observer=observer,
            rig_on_this_pc=self.rig.bus_config is not None and rig_on_this_pc(self.rig.bus_config))
        seed = self.rig.first_seed + self.tests_run
        self.tests_run += 1
        result = self._run(variant, valve_id, options, seed)
        retest = None
        if retest_of is not None and retest_of.record_dir is not None:
            decision = decide(result.verdict, variant.retest, result.advice.words)
            retest = decision.record_entry(retest_of.record_dir.name, retest_of.verdict)
        return self._store(result, folder[0] if folder else None, retest)

    def _run(self, variant: Variant, valve_id: str, options: Any, seed: int) -> Any:
        from edc_bench.bench import run_bench_test, run_simulated_test

        if self.rig.simulated:
            return run_simulated_test(variant, simulated_valve(variant, valve_id), seed, options=options,
                                      drift=self.rig.rig_drift, rack_fault=self.rig.rack_fault,
                                      sensor_fault=self.rig.sensor_fault)
        from edc_bench.protocol import default_icd
        from edc_bench.runtime.bus import ClosingBus, open_bus
        from edc_bench.runtime.clock import RealTimeClock

        with ClosingBus(open_bus(self.rig.bus_config, default_icd().bitrate)) as bus:
            return run_bench_test(bus, RealTimeClock(), variant, options)

    def _store(self, result: Any, folder: Path | None, retest: RetestSummary | None) -> TestDone:
        from edc_bench.history.store import index_record_dir
        from edc_bench.records.record import missing_files, write_record

        problems: list[str] = []
        try:
            record_dir = write_record(result, self.out_dir, figure=False, folder=folder, retest=retest)
        except OSError as exc:
            return TestDone(result, None, None, (f"the record could not be written ({exc}): free space on the disk, "
                                                 "then test the valve again",))
        missing = missing_files(record_dir)
        if missing:  # a full disk part way: the verdict stands, the record lacks data
            problems.append(f"the record {record_dir.name} is incomplete ("
                            + "; ".join(f"{k}: {v}" for k, v in missing.items())
                            + "): free space on the disk, then test the valve again")
        indexed = True
        try:  # indexed first: the report's page 1 prints the test's chain hash
            index_record_dir(record_dir, self.history_url)
        except Exception as exc:  # noqa: BLE001 - the record is safe; the history can take it later
            from edc_bench.history.secrets import known_secrets, redact

            indexed = False
            problems.append(redact(f"the history was not updated ({type(exc).__name__}: {exc}); add it later with: "
                                   f"edc-bench history --add {record_dir}", known_secrets(self.history_url)))
        return TestDone(result, record_dir, None, tuple(problems), indexed, _escalation(record_dir))

    def draw_reports(self, done: ValveDone) -> ValveDone:
        """Draw the report of each of the valve's tests (after its verdict is shown: a report takes seconds, which
        the technician should not wait for); ``done`` with their PDFs, and what failed in words.

        Not while a test runs: drawing competes with the real-time loop for this process.
        """
        from edc_bench.runtime.signals import stop_requested

        tests = []
        for test in done.tests:
            if test.record_dir is None or not self.report:
                tests.append(test)
            elif stop_requested():  # the session is ending (Ctrl-C or SIGTERM): no seconds spent drawing
                tests.append(replace(test, problems=(*test.problems, "no report drawn (interrupted); draw it with: "
                                                                     f"edc-bench report {test.record_dir}")))
            else:
                tests.append(self._draw(test))
        return replace(done, tests=tuple(tests))

    def _draw(self, test: TestDone) -> TestDone:
        try:
            from edc_bench.history.standing import history_standing
            from edc_bench.records.reader import load_record
            from edc_bench.records.report import draw_report

            record_dir = test.record_dir
            standing = (history_standing(load_record(record_dir), record_dir, self.history_url) if test.indexed
                        else None)
            report_pdf, _ = draw_report(record_dir, history_note=None if standing is None else standing.note())
        except Exception as exc:  # noqa: BLE001 - a report is redrawn later from the record; never lose the test
            return replace(test, problems=(*test.problems, f"the report could not be drawn ({type(exc).__name__}: "
                                                           f"{exc}); draw it with: edc-bench report {test.record_dir}"))
        return replace(test, report_pdf=report_pdf)


def _escalation(record_dir: Path) -> str:
    """The technician's line of the record's escalation ("" if none)."""
    from edc_bench.records.escalation_link import recorded_escalation

    escalated = recorded_escalation(record_dir)
    return escalated.words if escalated is not None else ""


__all__ = ["RigChoice", "SessionRunner", "TestDone", "ValveDone", "simulated_valve"]
