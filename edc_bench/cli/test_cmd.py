"""``edc-bench test``: run one bench test and write its record."""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import json
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

from edc_bench.cli.common import (
    MAX_SEED,
    add_bus_arguments,
    add_history_db_argument,
    add_pump_fault_arguments,
    add_rig_drift_argument,
    add_variant_arguments,
    given_path,
    identity,
    print_quietly_if_closed,
    seed_number,
)
from edc_bench.cli.exit_codes import ExitCode, exit_code_for
from edc_bench.cli.test_summary import TestSummary
from edc_bench.engine.outcome import AbortKind

if TYPE_CHECKING:
    from edc_bench.records.schema import Identity
    from edc_bench.runtime.bus_config import BusSettings
    from edc_bench.verdict.sections import RetestSummary


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Register the command."""
    p = sub.add_parser(
        "test",
        help="run a bench test (default: simulated rig, simulated time)",
        description="Run one bench test: drive the rack along the variant's reference, identify the valve's "
                    "friction (af) and damping (a1), and write a record folder. Without bus arguments the "
                    "simulated rig runs in process in simulated time. With --interface/--channel (or "
                    "python-can's config file or CAN_INTERFACE/CAN_CHANNEL environment variables) it drives "
                    "that bus in real time.",
    )
    add_variant_arguments(p)
    p.add_argument("--seed", type=seed_number, default=0, help="seed of the simulated rig's sensor noise (default: 0)")
    p.add_argument("--duration-s", type=_duration_s, default=None, metavar="S",
                   help="test duration in seconds (default: the variant's, 30 s)")
    p.add_argument("--estimator", choices=("rls", "gradient"), default=None,
                   help="override the variant's estimator (rls: recursive least squares; gradient: the paper's law)")
    p.add_argument("--realtime", action="store_true",
                   help="run in real time; without a bus, starts the simulated rig as a process and drives it over slcan")
    add_bus_arguments(p)
    p.add_argument("--valve-id", type=identity(), default=None, metavar="ID",
                   help="identity of the valve under test, kept as given in the record and the history (at most "
                        "100 characters; default on the simulated rig in simulated time: its --valve SPEC; in real time: none, with a "
                        "warning)")
    p.add_argument("--coil-temp-c", type=_coil_temp, default=None, metavar="C",
                   help="the coil's temperature at the start of the test, to refer its measured resistance to "
                        "20 degC (default: 20, a coil that has rested in the workshop; give it for a coil still "
                        "warm from earlier tests)")
    p.add_argument("--out", type=given_path, default=Path("records"), metavar="DIR",
                   help="folder for record folders (default: ./records)")
    p.add_argument("--json", action="store_true", help="print only a JSON summary on stdout")
    p.add_argument("--no-stiction", action="store_true",
                   help="simulated rig: Coulomb friction only (the plant the identification model assumes)")
    p.add_argument("--no-sensor-noise", action="store_true", help="simulated rig: exact sensor readings")
    p.add_argument("--adapter", default="none", metavar="SPEC",
                   help="simulated rig: the CAN adapter's timing between bench and rig: usb-fs (USB full-speed, "
                        "1.5-3.5 ms round trip) or latency_ms=L,jitter_ms=J,usb_frame_ms=F one way[,drift_ppm=D] "
                        "(default: none)")
    p.add_argument("--firmware", choices=("python", "c"), default="python",
                   help="simulated rig: its firmware, python (the prototype, default) or c (the C core; build it "
                        "with 'make -C firmware_proto/c')")
    add_rig_drift_argument(p)
    add_pump_fault_arguments(p)
    p.add_argument("--no-figure", action="store_true", help="do not draw report.png")
    p.add_argument("--pump-serial", type=identity(), default=None, metavar="SERIAL",
                   help="serial number of the pump, for the record")
    p.add_argument("--job-ref", type=identity(), default=None, metavar="REF",
                   help="the shop's job or vehicle reference, printed on the customer's page of the report")
    p.add_argument("--operator", type=identity(), default=None,
                   help="who ran the test (default: the login name)")
    p.add_argument("--station", type=identity(), default=None,
                   help="name of this bench station (default: the host name)")
    p.add_argument("--plain", action="store_true", help="log lines instead of the live panel, even on a terminal")
    add_history_db_argument(p, dest="history_db")
    p.add_argument("--no-history", action="store_true", help="do not add the test to the station's history")
    p.add_argument("--nominal-baseline", action="store_true",
                   help="judge a variant that has no measured new-valve baseline against the nominal one from its "
                        "physics (bring-up only: the verdict may be wrong, and the record, panel and report say "
                        "so); without it such a test is INVALID, 'variant not calibrated'")
    p.add_argument("--no-retest", action="store_true",
                   help="after a MARGINAL, do not test the valve again (by default the bench retests it at once and "
                        "the variant's [retest] rule says what the two tests decide)")
    p.add_argument("--full-length", action="store_true",
                   help="run the variant's whole excitation.duration_s; by default the test stops as soon as af and "
                        "a1 are known well enough that the verdict cannot change (or the model is known not to fit)")
    p.set_defaults(run=run)


def _variant(args: argparse.Namespace) -> Any:
    from edc_bench.config import load_variant, with_changes

    variant = load_variant(args.variant)
    changes: dict[str, dict[str, Any]] = {"excitation": {}, "estimator": {}}
    if args.duration_s is not None:
        changes["excitation"]["duration_s"] = args.duration_s
    if args.estimator is not None:
        changes["estimator"]["kind"] = args.estimator
    return with_changes(variant, changes, "command-line overrides")


def _bus_config(args: argparse.Namespace) -> BusSettings | None:
    """Bus settings from flags, python-can's environment or config file (checked); None for the in-process rig."""
    from edc_bench.cli.common import bus_settings

    return bus_settings(args.interface, args.channel, args.bitrate, configured_alone=True, options=args.bus_options)


def _duration_s(text: str) -> float:
    """``--duration-s``: a test length in seconds, above 0 and at most 600 (a variant's longest)."""
    from edc_bench.cli.common import positive_float

    value = positive_float("the test length in seconds, e.g. 30")(text)
    if value > 600:
        raise argparse.ArgumentTypeError(f"{text} s: a test lasts at most 600 s (10 minutes); e.g. 30")
    return value


def _calibrate_command(variant: Any, bus_config: BusSettings | None) -> str:
    """The exact calibrate command for this variant on this rig (the simulated rig: a simulated new valve)."""
    from edc_bench.verdict.judgement import default_calibrate_command

    words = ["--valve", "new"] if bus_config is None else [
        word for key in ("interface", "channel", "bitrate") if bus_config.get(key) is not None
        for word in (f"--{key}", str(bus_config[key]))] + [
        word for key, value in bus_config.items() if key not in ("interface", "channel", "bitrate")
        for word in ("--bus-option", f"{key}={value}")]
    return default_calibrate_command(variant, words)


def _coil_temp(text: str) -> float:
    """``--coil-temp-c``: a plausible coil temperature in degC."""
    import argparse
    import math

    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number (degC, e.g. 20 or 45)") from None
    if not math.isfinite(value) or not -40.0 <= value <= 150.0:
        raise argparse.ArgumentTypeError(f"{text!r} is not a plausible coil temperature (-40 to 150 degC)")
    return value


def run(args: argparse.Namespace) -> int:
    """Run the test, write the record, report."""
    from edc_bench.runtime.signals import interrupt_guard, settle, stop_requested

    if not args.no_history:
        from edc_bench.cli.common import check_history_url

        check_history_url(args.history_db)  # a test is minutes; a wrong database is refused before it
        _check_chain_model(args)
    # the first Ctrl-C aborts the test; later ones cannot cost the record; 130 is said here, in this command's words
    with interrupt_guard(reraise=False):
        ran = _run_guarded(args)
        code = (ExitCode.RECORD_NOT_WRITTEN if ran.figure_lost and ran.code != ExitCode.INTERNAL_ERROR
                else ran.code)  # a figure a full disk cost is no clean exit, after the retest it did not hold up
        # what is said from here stands: a signal now is only noted (the guard's end puts back a handler that
        # would raise, and a second Ctrl-C would make a said PASS an exit 130)
        settle(raise_swallowed=False)
        if not stop_requested() or code in (ExitCode.INTERNAL_ERROR, ExitCode.RECORD_NOT_WRITTEN):
            return code
        if ran.last is None or _interrupted(ran.last.result):
            # the record is written (INVALID, "interrupted by the operator"); the exit code says who ended it
            print("edc-bench test: interrupted by the operator; the record is written (INVALID)", file=sys.stderr)
            return ExitCode.INTERRUPTED
        # the signal came once the test had ended: its verdict, recorded and said, stands (one decision, not a
        # PASS said and then an INVALID exit); what the interrupt cut short is said with it
        verdict = ran.last.decision.verdict if ran.last.decision is not None else ran.last.result.verdict
        print(f"edc-bench test: interrupted after the test had ended: {verdict} stands, as its record "
              f"{ran.last.record_dir} holds it"
              + ("; the retest was not run: test the valve again for its decision" if ran.retest_skipped else ""),
              file=sys.stderr)
        return code


def _interrupted(result: Any) -> bool:
    """Whether the operator's interrupt cut this test short (its record says INVALID, interrupted)."""
    abort = result.outcome.abort
    return abort is not None and abort.kind is AbortKind.INTERRUPTED


def _check_chain_model(args: argparse.Namespace) -> None:
    """On a chain's station, refuse to judge with a model the chain does not record for it (an adoption that
    bypassed the chain). A chain that cannot be reached now is not checked: the test goes on, and its indexing says
    what is wrong after it."""
    from edc_bench.history.url import default_url

    url = args.history_db or default_url()
    if not url.startswith("postgresql"):  # a chain's history is a server's, however its URL is spelled
        return
    from edc_bench.station_settings import default_station

    from edc_bench.errors import ConfigError, EdcBenchError
    from edc_bench.history.store import HistoryStore
    from edc_bench.history.chain_adoption import chain_model_problem, chain_station
    from edc_bench.verdict.classifier import file_sha256, station_model_path

    try:
        with HistoryStore(url) as store:
            station = chain_station(store, args.station or default_station())
            problem = chain_model_problem(store, station, file_sha256(station_model_path()))
    except (EdcBenchError, OSError):  # the chain or the model file cannot be read now: said after the test
        return
    if problem:
        raise ConfigError(problem)


def _identity(args: argparse.Namespace) -> Identity:
    import getpass

    from edc_bench.records.schema import Identity
    from edc_bench.station_settings import default_station, station_identity

    try:
        operator = args.operator or getpass.getuser()
    except (KeyError, OSError):  # no user name in this environment
        operator = ""
    shop = station_identity()
    return Identity(pump_serial=args.pump_serial or "", station=args.station or default_station(),
                    station_shown=shop.for_customers(args.station), operator=operator, shop=shop.shop,
                    shop_address=shop.shop_address, job_ref=args.job_ref or "")


def _live(args: argparse.Namespace) -> bool:
    """True when the live panel shows the test (a terminal, neither --json nor --plain)."""
    return not args.json and not args.plain and sys.stdout.isatty()


def _observer(args: argparse.Namespace, title: str) -> Any:
    """The live panel on a terminal, log lines on stderr otherwise, nothing with --json."""
    import contextlib

    if args.json:
        return contextlib.nullcontext(None)
    if _live(args):
        from edc_bench.ui.live import LiveView

        return LiveView(title)
    from edc_bench.ui.plain import PlainLog

    return contextlib.nullcontext(PlainLog(sys.stderr))


@dataclasses.dataclass(frozen=True)
class _Ran:
    """What ``test`` did: its exit code, its last test (None: none was stored) and whether an interrupt that came
    after a MARGINAL kept its retest from running."""

    code: int
    last: _Tested | None = None
    retest_skipped: bool = False
    figure_lost: bool = False  # a test's report.png not written for a full disk


def _run_guarded(args: argparse.Namespace) -> _Ran:
    from edc_bench.cli.common import check_output_folder

    check_output_folder(args.out, "--out")  # before the test, not after it
    variant = _variant(args)
    bus_config = _bus_config(args)
    _check_rig_flags(args, variant, bus_config)
    with _bus_opened_ahead(bus_config) as opened:
        return _test_and_retest(args, variant, bus_config, opened)


@contextlib.contextmanager
def _bus_opened_ahead(bus_config: BusSettings | None) -> Iterator[Any]:
    """The bus of the first test, opened before anything is said or shown: a bus that does not open is one line
    (exit 3), not a warning and a panel before it. The test closes it; if the test never ran, leaving does."""
    if bus_config is None:
        yield None
        return
    from edc_bench.protocol import default_icd
    from edc_bench.runtime.bus import ClosingBus, open_bus

    opened = ClosingBus(open_bus(bus_config, default_icd().bitrate))
    try:
        yield opened
    finally:
        opened.__exit__(None, None, None)  # closes once: nothing left to do after the test closed it


def _test_and_retest(args: argparse.Namespace, variant: Any, bus_config: BusSettings | None, opened: Any) -> _Ran:
    """The test, and after a MARGINAL its retest (the first test on ``opened``, the bus opened ahead, if any)."""
    from edc_bench.runtime.signals import stop_requested
    from edc_bench.verdict.retest import retest_wanted

    simulated = bus_config is None and not args.realtime
    # a simulated valve is named by its spec; a valve on a bus is named only by the technician
    valve_id = args.valve_id or (args.valve if simulated else "")
    if not valve_id:
        print("edc-bench test: warning: no --valve-id: the record and the history name no valve (the bench cannot "
              "read it off the valve); give --valve-id ID to follow this valve in 'edc-bench history --trend' "
              "and 'edc-bench label'", file=sys.stderr)
    first = _test_once(args, variant, bus_config, valve_id, args.seed, retest_of=None, opened=opened)
    wanted = not args.no_retest and retest_wanted(first.result.verdict, variant.retest)
    if (first.record_dir is None or first.code in (ExitCode.INTERNAL_ERROR, ExitCode.RECORD_NOT_WRITTEN)
            or stop_requested() or not wanted):
        if args.json:
            print_quietly_if_closed(lambda: print(json.dumps(TestSummary.of(first.result, first.record_dir).as_json(),
                                                             indent=2)))
        return _Ran(first.code, first if first.record_dir is not None else None,
                    retest_skipped=wanted and stop_requested(), figure_lost=first.figure_lost)
    # the MARGINAL procedure: the valve stays mounted and is tested again; on the simulated rig with new noise
    retest_seed = (args.seed + 1) % (MAX_SEED + 1)
    if not args.json:
        print("\nretest: MARGINAL is near the limit; the bench tests the valve again now"
              + (f" (simulated rig: noise seed {retest_seed})" if bus_config is None else "")
              + ". Leave the valve mounted.", flush=True)
    second = _test_once(args, variant, bus_config, valve_id, retest_seed, retest_of=first)
    if second.decision is None:  # not written, or a bug: said already
        return _Ran(second.code, figure_lost=first.figure_lost)
    if args.json:
        out = dataclasses.replace(TestSummary.of(second.result, second.record_dir, second.decision),
                                  first_test=TestSummary.of(first.result, first.record_dir))
        print_quietly_if_closed(lambda: print(json.dumps(out.as_json(), indent=2)))
    elif _live(args):
        from rich.console import Console

        from edc_bench.ui.live import decision_panel

        Console().print(decision_panel(second.decision, first.result.verdict, second.result.verdict))
    else:
        print_quietly_if_closed(lambda: print(f"\ndecision: {second.decision.verdict}, {second.decision.words} "
                                              f"(first test MARGINAL, retest {second.result.verdict}; "
                                              f"rule {second.decision.rule})"))
    if second.code == ExitCode.RECORD_NOT_WRITTEN or (stop_requested() and _interrupted(second.result)):
        return _Ran(second.code, second, figure_lost=first.figure_lost or second.figure_lost)  # 74 too
    return _Ran(exit_code_for(second.decision.verdict), second, figure_lost=first.figure_lost or second.figure_lost)


@dataclasses.dataclass(frozen=True)
class _Tested:
    """One test run, stored and shown: its result, record folder, exit code, and (a retest) what the pair decided."""

    result: Any
    record_dir: Path | None
    code: int
    decision: Any = None
    figure_lost: bool = False  # report.png not written for a full disk: the run's exit is 74


def _test_once(args: argparse.Namespace, variant: Any, bus_config: BusSettings | None, valve_id: str, seed: int,
               retest_of: _Tested | None, opened: Any = None) -> _Tested:
    """Run one test on the rig the flags name (a bus: ``opened`` ahead, or here), write its record, add it to the
    history and show its verdict."""
    folder: list[Path] = []
    options = _options(args, variant, bus_config, valve_id, folder)
    simulated = bus_config is None and not args.realtime
    where = ("simulated rig, simulated time" if simulated else
             "simulated rig process, real time" if bus_config is None else f"bus {bus_config}, real time")
    which = "retest of " if retest_of is not None else ""
    title = (f"edc-bench test: {which}{variant.name} ({variant.pump.part_number}), valve {valve_id or '?'}, "
             f"{where}")
    with _observer(args, title) as observer:
        if observer is not None:
            observer.phase("connect")
        result, notes = _run(args, variant, bus_config, dataclasses.replace(options, observer=observer), seed,
                             opened)
    decision = retest = None
    if retest_of is not None:
        from edc_bench.verdict.retest import decide

        decision = decide(result.verdict, variant.retest, result.advice.words)
        retest = decision.record_entry(retest_of.record_dir.name, retest_of.result.verdict)
    record_dir, code = _finish(args, result, folder[0] if folder else None, notes, retest)
    lost = record_dir is not None and code != ExitCode.INTERNAL_ERROR and _figure_lost(args, record_dir)
    return _Tested(result, record_dir, code, decision if record_dir is not None else None, figure_lost=lost)


def _check_rig_flags(args: argparse.Namespace, variant: Any, bus_config: BusSettings | None) -> None:
    """Refuse a bad --adapter or --valve before any work; warn about flags that do not apply to a real bus."""
    from edc_bench.physics.valve import parse_valve_spec
    from edc_bench.sim.adapter import parse_adapter

    parse_adapter(args.adapter)
    if bus_config is None:
        parse_valve_spec(args.valve, variant)  # before the panel or the rig starts
        if args.firmware == "c":
            from edc_bench.errors import ConfigError
            from firmware_proto.c_firmware import CFirmwareMissing, load_library

            try:
                load_library()
            except CFirmwareMissing as exc:
                raise ConfigError(str(exc)) from None
    if args.adapter != "none" and bus_config is not None:
        print("edc-bench test: warning: --adapter simulates an adapter for the simulated rig; a real bus has its "
              "own timing", file=sys.stderr)
    simulated_only = [flag for flag, given in (("--no-stiction", args.no_stiction),
                                               ("--no-sensor-noise", args.no_sensor_noise),
                                               ("--firmware", args.firmware != "python"),
                                               ("--rig-drift", args.rig_drift is not None),
                                               ("--rack-fault", args.rack_fault is not None),
                                               ("--sensor-fault", args.sensor_fault is not None)) if given]
    if bus_config is not None and simulated_only:
        print(f"edc-bench test: warning: {', '.join(simulated_only)} describe the simulated rig; on a real bus the "
              "valve mounted is what is tested", file=sys.stderr)


def _options(args: argparse.Namespace, variant: Any, bus_config: BusSettings | None, valve_id: str,
             folder: list[Path]) -> Any:
    """The test's options from the command line; ``folder`` receives the record folder once the CAN log starts."""
    from edc_bench.bench import BenchOptions
    from edc_bench.records.writer import CAN_LOG_FILE, new_record_dir
    from edc_bench.runtime.bus_config import rig_on_this_pc

    def stream_target(started: str) -> Path:
        # the record folder exists from the first frame on: a killed test leaves its CAN log; it is named by the
        # test's own start, the record's started_at
        folder.append(new_record_dir(args.out, valve_id, variant.name, started))
        return folder[0] / CAN_LOG_FILE

    return BenchOptions(valve_id=valve_id, identity=_identity(args), coil_temp_c=args.coil_temp_c,
                        nominal_baseline=args.nominal_baseline, full_length=args.full_length,
                        calibrate_command=_calibrate_command(variant, bus_config), stream_can_log=stream_target,
                        rig_on_this_pc=args.realtime if bus_config is None else rig_on_this_pc(bus_config))


def _run(args: argparse.Namespace, variant: Any, bus_config: BusSettings | None,
         options: Any, seed: int, opened: Any = None) -> tuple[Any, list[str]]:
    """Run the test on the rig the flags name (on a bus: ``opened``, the :class:`~edc_bench.runtime.bus.ClosingBus`
    opened ahead, else opened here); the result, and what the record should note of the bus after it."""
    from edc_bench.bench import run_bench_test, run_simulated_test
    from edc_bench.physics.valve import parse_valve_spec
    from edc_bench.protocol import default_icd
    from edc_bench.runtime.bus import ClosingBus, open_bus
    from edc_bench.runtime.clock import RealTimeClock
    from edc_bench.runtime.priority import realtime_priority

    # the panel's title says it all; a line on stderr would only tear the panel
    quiet = args.json or _live(args)
    log = (lambda line: None) if quiet else (lambda line: print(line, file=sys.stderr, flush=True))
    if bus_config is None and not args.realtime:
        log(f"edc-bench test: variant {variant.name}, simulated rig (valve {args.valve}, seed {seed}), "
            f"simulated time, at most {variant.excitation.duration_s:g} s")
        return run_simulated_test(variant, parse_valve_spec(args.valve, variant), seed,
                                  stiction=not args.no_stiction, sensor_noise=not args.no_sensor_noise,
                                  adapter=args.adapter, options=options, firmware=args.firmware,
                                  drift=args.rig_drift, rack_fault=args.rack_fault, sensor_fault=args.sensor_fault), []
    icd = default_icd()
    if bus_config is not None:
        log(f"edc-bench test: variant {variant.name}, bus {bus_config}, real time")
        session = opened if opened is not None else ClosingBus(open_bus(bus_config, icd.bitrate))
        with session as bus:
            result = run_bench_test(bus, RealTimeClock(), variant, options)
        return result, _closing_notes(session)
    from edc_bench.errors import RigError
    from edc_bench.runtime.signals import stop_requested
    from edc_bench.sim.process import rig_process

    rig_status: dict[str, float] = {}
    drift = [] if args.rig_drift is None else ["--rig-drift", args.rig_drift.spec()]
    drift += [] if args.rack_fault is None else ["--rack-fault", args.rack_fault.spec()]
    drift += [] if args.sensor_fault is None else ["--sensor-fault", args.sensor_fault.spec()]
    try:
        # raised before the rig process starts: it inherits the policy and is put one above the bench
        with realtime_priority(), rig_process(args.variant, args.valve, seed, args.adapter, rig_status,
                                              extra=["--firmware", args.firmware, *drift]) as channel:
            log(f"edc-bench test: variant {variant.name}, simulated rig process at {channel}, real time")
            session = ClosingBus(open_bus({"interface": "slcan", "channel": channel}, icd.bitrate))
            with session as bus:
                result = run_bench_test(bus, RealTimeClock(), variant, options)
    except RigError:
        # Ctrl-C at the terminal reaches the rig process too (one process group): a rig that stopped for it while
        # starting is the operator's interrupt (130), not a rig fault (3); no test started, so there is no record
        if stop_requested():
            raise KeyboardInterrupt from None
        raise
    # the rig process's side of the timing (how long it once went without serving: a disturbed rig), known once it
    # has stopped
    from edc_bench.records.simulation import RigProcessSummary, SimulationSummary

    simulation = SimulationSummary(rig_process=RigProcessSummary(
        valve=args.valve, seed=seed, adapter=args.adapter, firmware=args.firmware,
        worst_gap_ms=rig_status.get("worst_gap_ms"),
        sensor_drift=None if args.rig_drift is None else args.rig_drift.spec(),
        rack_fault=None if args.rack_fault is None else args.rack_fault.spec(),
        sensor_fault=None if args.sensor_fault is None else args.sensor_fault.spec()))
    return dataclasses.replace(result, simulation=simulation), _closing_notes(session)


def _value_and_spread(value: float, std: float) -> str:
    """``0.0696 +/- 0.0004``; a figure not identified says so (an aborted test), never "nan"."""
    import math

    if not math.isfinite(value):
        return "not identified"
    return f"{value:.6g}" + (f" +/- {std:.2g}" if math.isfinite(std) else " (no spread: too few periods)")


def _closing_notes(session: Any) -> list[str]:
    """A connection that died with the test (:class:`~edc_bench.runtime.bus.ClosingBus`): noted in the record,
    which is what matters."""
    return [f"closing the bus failed: {session.close_error}"] if session.close_error else []


def _finish(args: argparse.Namespace, result: Any, folder: Path | None, notes: list[str],
            retest: RetestSummary | None = None) -> tuple[Path | None, int]:
    """Write the record, add it to the history, show the verdict (``--json``: the caller prints the summary); the
    record folder and the exit code."""
    record_dir, record_error, whole = _write_record(result, args, folder, notes, retest)
    if record_dir is None:
        _report(args, result, None)
        print(f"edc-bench test: error: the record could not be written ({record_error}). The verdict above was "
              "not saved: free space on the disk or give a writable --out, then test the valve again.",
              file=sys.stderr)
        return None, ExitCode.RECORD_NOT_WRITTEN
    if record_error and whole:
        print(f"edc-bench test: warning: {record_error}", file=sys.stderr)
    saved_elsewhere = not record_dir.resolve().is_relative_to(Path(args.out).resolve())  # moved later, added then
    abort = result.outcome.abort
    if abort is not None and abort.kind is AbortKind.INTERNAL_ERROR:
        if not (args.no_history or saved_elsewhere):
            _index(record_dir, args.history_db)
        print(f"edc-bench test: {result.outcome.abort_reason}\nThis is a bug in edc-bench; the rig was sent SAFE and "
              f"the record {record_dir} holds the data and the traceback.", file=sys.stderr)
        return record_dir, ExitCode.INTERNAL_ERROR
    _report(args, result, record_dir)  # the verdict first: the history (a server, perhaps slow) comes after it
    _report_escalation(args, record_dir)
    if not (args.no_history or saved_elsewhere):
        from edc_bench.history.url import default_url

        if not args.json and not (args.history_db or default_url()).startswith("sqlite"):  # a server: say we wait
            print("saving the test to the history...", file=sys.stderr, flush=True)
        history_error = _index(record_dir, args.history_db)
        if history_error:
            print(f"edc-bench test: warning: the history was not updated ({history_error}); the record is "
                  f"{'complete' if whole else 'on disk'}. Add it later with: edc-bench history --add {record_dir}",
                  file=sys.stderr)
    if not whole:  # a record missing a part (a full disk part way) is no clean exit: the verdict stands, its data not
        print(f"edc-bench test: error: {record_error}. The verdict above stands, but the test cannot be replayed "
              f"or shown whole from {record_dir}: free space on the disk, then test the valve again.",
              file=sys.stderr)
        return record_dir, ExitCode.RECORD_NOT_WRITTEN
    return record_dir, exit_code_for(result.verdict)


def _figure_lost(args: argparse.Namespace, record_dir: Path) -> bool:
    """Say a figure the test could not write (report.png); True when a full disk is why (the run's exit is then
    74, after a MARGINAL's retest: the data is whole and the retest needs none of it)."""
    from edc_bench.records.reader import load_record
    from edc_bench.records.writer import FIGURE_FILE

    if args.no_figure:
        return False
    try:
        files = load_record(record_dir).files
    except Exception:  # noqa: BLE001 - the record was just written; a reader's refusal is said elsewhere
        return False
    if files.figure_error is None:  # drawn, or a test without a trace: nothing to draw
        return False
    redraw = (f"the record holds the data; 'edc-bench report {record_dir}' draws the test's report (its PDF and "
              "page images) from it")
    if files.figure_no_room:
        print(f"edc-bench test: error: {record_dir / FIGURE_FILE} could not be written ({files.figure_error}): the "
              f"disk is full. The verdict above stands and {redraw} once there is room.", file=sys.stderr)
        return True
    print(f"edc-bench test: warning: {record_dir / FIGURE_FILE} could not be drawn ({files.figure_error}): a bug in "
          f"edc-bench, said in the record. The verdict above stands and {redraw}.", file=sys.stderr)
    return False


def _report_escalation(args: argparse.Namespace, record_dir: Path) -> None:
    """The same valve not judged twice, both times for a cause the valve itself can cause: said under the verdict
    (``--json``: in the summary)."""
    from edc_bench.records.escalation_link import recorded_escalation

    escalated = recorded_escalation(record_dir)
    if escalated is None or args.json:
        return
    print_quietly_if_closed(lambda: print(f"\nESCALATE: {escalated.words} (the earlier test: record "
                                          f"{escalated.of_record})"))


def _report(args: argparse.Namespace, result: Any, record_dir: Path | None) -> None:
    """The verdict for the technician: JSON, the verdict panel, or plain lines."""
    if args.json:
        return  # one summary for the whole run, printed by the caller (a retest's holds its first test's)
    if _live(args):
        from rich.console import Console

        from edc_bench.ui.live import verdict_panel

        Console().print(verdict_panel(result, record_dir))
    else:
        print_quietly_if_closed(lambda: _print_report(result, record_dir))


def _write_record(result: Any, args: argparse.Namespace, folder: Path | None, notes: list[str],
                  retest: RetestSummary | None = None) -> tuple[Path | None, str | None, bool]:
    """Write the record under ``--out``; if its record.json cannot be written (a full disk), into a new folder in
    the temp folder.

    Returns
    -------
    (folder, problem, whole)
        The record folder (None if it could not be written anywhere), what went wrong on the way, and whether the
        record holds every data file (a trace or CAN log the disk had no room for leaves it incomplete).
    """
    import tempfile

    from edc_bench.records.record import missing_files, write_record

    def incomplete(written: Path) -> str | None:
        missing = missing_files(written)
        return "; ".join(f"{k}: {v}" for k, v in missing.items()) if missing else None

    try:
        written = write_record(result, args.out, figure=not args.no_figure, folder=folder, notes=notes,
                               retest=retest)
        missing = incomplete(written)
        return written, None if missing is None else f"the record is incomplete: {missing}", missing is None
    except OSError as exc:
        first = f"{type(exc).__name__}: {exc}"
    notes = [*notes, f"the record could not be written under {args.out} ({first})"]
    try:
        fallback = Path(tempfile.mkdtemp(prefix="edc-bench-record-"))
        written = write_record(result, fallback, figure=False, folder=fallback, notes=notes, retest=retest)
    except OSError as exc:
        return None, f"under {args.out}: {first}; in the temp folder: {type(exc).__name__}: {exc}", False
    missing = incomplete(written)
    if missing is not None:
        return written, (f"the record could not be written under {args.out} ({first}), and in {written} it is "
                         f"incomplete: {missing}" + (f"; what was written under {args.out} is in {folder}"
                                                     if folder is not None and folder.exists() else "")), False
    left = _remove_half_written(folder)  # the CAN log streamed there is whole in the saved record
    return written, (f"the record could not be written under {args.out} ({first}); it was saved to {written} "
                     "instead and is not in the history: move it to the records folder once there is room, then "
                     "add it with: edc-bench history --add FOLDER"
                     + (f"; {folder} holds what was written there before the disk filled ({left}): remove it"
                        if left else "")), True


def _remove_half_written(folder: Path | None) -> str:
    """Remove the record folder a full disk left without its record.json (its CAN log, streamed there while the
    test ran, is whole in the record saved elsewhere); what could not be removed, said ("" when nothing is left)."""
    import shutil

    from edc_bench.records.writer import RECORD_FILE

    if folder is None or not folder.is_dir() or (folder / RECORD_FILE).exists():
        return ""
    try:
        shutil.rmtree(folder)
    except OSError as exc:
        return f"it could not be removed: {exc}"
    return ""


def _index(record_dir: Path, url: str | None) -> str | None:
    """Add the record to the station's history; the reason if that failed (the record is safe either way)."""
    from edc_bench.errors import EdcBenchError
    from edc_bench.history.secrets import known_secrets, redact
    from edc_bench.history.store import index_record_dir

    try:
        index_record_dir(record_dir, url)
    except EdcBenchError as exc:
        return redact(str(exc), known_secrets(url))
    except Exception as exc:  # noqa: BLE001 - a database problem must not cost the verdict's report
        return redact(f"{type(exc).__name__}: {exc}", known_secrets(url))
    return None


def _print_report(result: Any, record_dir: Path | None) -> None:
    from edc_bench.identification.analysis import model_fit_line
    from edc_bench.identification.coil_check import coil_line
    from edc_bench.records.baseline_text import baseline_line

    from edc_bench.verdict.part_words import part_line

    print(f"verdict: {result.verdict}, {result.advice.words}")
    for reason in result.reasons:
        print(f"  - {reason}")
    if result.judgement.part is not None:
        print(f"part at fault: {part_line(result.judgement.part)}")
    f, volt = result.features, result.judgement.features_volt
    if f.identified:
        print(f"features: af = {f.af:.5f} V, a1 = {f.a1:.6f} V s/mm "
              f"(referred to the reference coil, {result.variant.coil.resistance_ohm:g} ohm at 20 degC; with this "
              f"coil: af {volt.af:.5f} V, a1 {volt.a1:.6f})")
    else:
        print("features: af and a1 not identified (the test ended before they could be)")
    print(f"coil: {coil_line(result.judgement.coil)}")
    if result.judgement.baseline is not None:
        print(f"baseline: {baseline_line(result.judgement.baseline)}")
    if result.classification is not None:
        c = result.classification
        print(f"relative to the new-valve baseline: af x{c.features_rel.af:.2f}, a1 x{c.features_rel.a1:.2f}")
    print("parameters:")
    for name, p in result.parameters.items():
        tail = ""
        if p.truth is not None and p.error_rel is not None:
            tail = f"   truth {p.truth:.6g} ({p.error_rel:+.1%})"
        kind = "" if p.estimated else "   (fixed at nominal)"
        print(f"  {name:>2} = {_value_and_spread(p.value, p.std)}{tail}{kind}")
    ident = result.identification
    if ident is not None:
        print(f"converged: {result.converged} ({ident.periods} excitation periods of {ident.period_s:g} s; "
              f"condition number {ident.condition_number:.3g})")
        if ident.model_fit is not None:
            fit = ident.model_fit
            print(f"model fit: {model_fit_line(fit)}" + ("" if fit.fits else " - DOES NOT FIT"))
    if result.stop is not None:
        print(f"stopped: {result.stop.reason} at {result.stop.time_s:.1f} s")
    t = result.timing
    if t.ticks:
        print(f"timing: {t.ticks} ticks, lateness p99 {t.lateness_p99_us:.0f} us, ticks late {t.ticks_late}, "
              f"missed replies {result.outcome.missed_replies}, CPU steal meanwhile {t.cpu_steal_s:.2f} s")
        if t.scheduling is not None:
            print(f"priority: {t.scheduling}")
    if record_dir is None:
        print("record: not written (see the error below)")
        return
    print(f"record: {record_dir}")
    print(f"report: edc-bench report {record_dir}")
