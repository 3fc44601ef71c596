"""``edc-bench calibrate``: measure a variant's new-valve baseline (af0, a1_0), valve by valve on a rig."""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

from edc_bench.cli.common import add_bus_arguments, count_up_to, given_path, identity, seed_number
from edc_bench.cli.exit_codes import ExitCode
from edc_bench.verdict.baseline_source import BaselineSource, sources_text

if TYPE_CHECKING:
    from edc_bench.records.schema import Identity
    from edc_bench.runtime.bus_config import BusSettings


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Register the command."""
    p = sub.add_parser(
        "calibrate", help="measure a variant's new-valve baseline",
        description="Run bench tests of new valves and compute the variant's baseline: the mean af and a1, their "
                    "spread and the uncertainty of the mean, against which every test's features are judged. "
                    "Where the tests run: with --interface/--channel on that rig in real time, on the valve "
                    "mounted; with --valve SPEC on the simulated rig (the full loop, simulated time); with "
                    "neither, on a simulated population of new valves (the shipped baselines). On a rig, "
                    "calibrate valve by valve: mount a known-new valve, run with --append, repeat; each run adds "
                    "its converged tests to the station's baseline. Exit code 12: no converged test (the reasons "
                    "are printed).",
    )
    p.add_argument("--variant", default=None, metavar="NAME|PART|PATH", help="pump variant (default: p-edc-default)")
    p.add_argument("--tests", type=count_up_to(100, " (each test is a valve, or 30 s of a simulated one)"), default=None,
                   help="tests to run (default: 1 on a rig or with --valve, where each run is one valve; "
                        "20 for a simulated population)")
    how = p.add_mutually_exclusive_group()
    how.add_argument("--append", action="store_true",
                   help="add the converged tests to the station's baseline of this variant (made if it has none) "
                        "and write it; the earlier file is kept in baselines/earlier/")
    how.add_argument("--write", action="store_true",
                   help="write a new station baseline from these tests alone (the earlier one is kept in "
                        "baselines/earlier/); default: print the baseline only")
    p.add_argument("--baseline-file", type=given_path, default=None, metavar="FILE",
                   help="write the baseline to this file instead of the station's (e.g. configs/baselines/"
                        "<variant>.toml for a shipped variant)")
    p.add_argument("--valve", default=None, metavar="SPEC",
                   help="calibrate on the simulated rig with this simulated valve (new, or physical values such as "
                        "clearance=0.09), through the full loop as 'edc-bench test' runs it")
    p.add_argument("--valve-id", type=identity(), default=None, metavar="ID",
                   help="identity of the valve mounted, for the records")
    p.add_argument("--pump-serial", type=identity(), default=None, metavar="SERIAL",
                   help="serial number of the pump the valve is mounted in: pumps of one type differ by their return "
                        "spring, so a baseline over valves in several pumps (3 or more) judges the rack-travel "
                        "sensor more finely than one from a single pump (docs/diagnosis.md)")
    p.add_argument("--seed", type=seed_number, default=None,
                   help="seed of the simulated rig's noise or the simulated population (default: 100 plus the "
                        "tests already in the baseline; each test adds its number)")
    add_bus_arguments(p, interface_help="python-can interface of a real rig, e.g. slcan, socketcan, pcan",
                      channel_help="python-can channel of a real rig, e.g. socket://127.0.0.1:5000 or can0")
    p.add_argument("--out", type=given_path, default=Path("records"), metavar="DIR",
                   help="folder for the calibration tests' records (default: ./records), as in 'edc-bench test'")
    p.add_argument("--station", type=identity(), default=None,
                   help="name of this bench station (default: the host name)")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    """Run the tests, pool them, print and write the baseline.

    Ctrl-C or SIGTERM ends the calibration with no baseline printed or written (exit 130): a test on a rig ends
    first as an abort (SAFE sent, its record written); a simulated population stops at once.
    """
    from edc_bench.cli.common import bus_settings
    from edc_bench.config import load_variant
    from edc_bench.errors import ConfigError
    from edc_bench.runtime.signals import interrupt_guard

    bus = bus_settings(args.interface, args.channel, args.bitrate, configured_alone=False, options=args.bus_options)
    rig = bus is not None
    if rig and args.valve is not None:
        raise ConfigError("--valve simulates a valve on the simulated rig; with --interface/--channel the valve is "
                          "the one mounted on the rig: give one or the other")
    tests = args.tests if args.tests is not None else (1 if rig or args.valve is not None else 20)
    if args.out.suffix == ".toml":
        raise ConfigError(f"--out {args.out}: --out is the folder for the tests' records, as in 'edc-bench test'; "
                          "write the baseline to a file with --baseline-file FILE")
    variant = load_variant(args.variant)
    target, earlier = _target_and_earlier(args, variant)
    # each appended run of a simulated valve gets fresh noise unless a seed is given
    seed = args.seed if args.seed is not None else 100 + len(earlier)
    if rig or args.valve is not None:
        # a test ends safely and keeps its record, then the guard raises the interrupt: no more tests, no baseline
        with interrupt_guard():
            measured = (_rig_tests(args, bus, variant, tests) if rig
                        else _simulated_rig_tests(args, variant, tests, seed))
    else:  # no rig and no record: Ctrl-C stops the population where it is
        from edc_bench.population.calibrate import population_tests

        from edc_bench.runtime.signals import stop_if_interrupted

        print(f"calibrating {variant.name} on {tests} simulated new valves (seed {seed})", file=sys.stderr)
        measured = population_tests(variant, tests, seed)
        stop_if_interrupted()  # a library that caught the KeyboardInterrupt ran the population on: still Ctrl-C
        print(f"{len(measured)} of {tests} tests converged", file=sys.stderr)
    if not measured:
        unchanged = f"; the baseline {target} is unchanged" if earlier else ", so no baseline"
        print(f"edc-bench calibrate: no converged new-valve test{unchanged} (the reasons are above); check the "
              f"valve is new and mounted, then run again", file=sys.stderr)
        return ExitCode.INVALID
    _write_baseline(args, variant, target, earlier, measured)
    return ExitCode.OK


def _target_and_earlier(args: argparse.Namespace, variant: Any) -> tuple[Path | None, list[Any]]:
    """Where the baseline goes (checked before minutes of tests, not after), and the tests it holds already."""
    from edc_bench.cli.common import check_output_folder
    from edc_bench.errors import ConfigError
    from edc_bench.verdict.baseline import read_baseline, station_baseline_path

    target = args.baseline_file or (station_baseline_path(variant.name) if args.write or args.append else None)
    check_output_folder(args.out, "--out")
    if target is not None:
        _check_writable(target)
        if target.is_file():
            try:
                read_baseline(target)
            except ConfigError:
                raise ConfigError(f"--baseline-file {target}: the file there is not a baseline (is it the variant "
                                  "file?); refusing to replace it: give another file") from None
    if args.valve is not None:
        _refuse_worn_valve(args.valve, variant)
    if not (args.append and target is not None and target.is_file()):
        return target, []
    pool = read_baseline(target, variant.name)
    if pool.tests and not pool.test_list:
        raise ConfigError(f"{target}: this baseline does not list its tests (an older edc-bench wrote it), so "
                          "tests cannot be added to it: calibrate anew with --write")
    return target, list(pool.test_list)


def _write_baseline(args: argparse.Namespace, variant: Any, target: Path | None, earlier: list[Any],
                    measured: list[Any]) -> None:
    """Pool the tests into the baseline, print it with what to do next, and write it where asked."""
    import datetime
    import shlex
    from edc_bench.station_settings import default_station

    from edc_bench import __version__
    from edc_bench.records.baseline_text import baseline_line
    from edc_bench.verdict.baseline import RECOMMENDED_TESTS, baseline_from_tests, write_baseline

    sources = frozenset(t.source or BaselineSource.UNKNOWN for t in [*earlier, *measured])
    if len(sources) > 1:
        print(f"edc-bench calibrate: warning: the baseline mixes tests from {sources_text(sources)}",
              file=sys.stderr)
    baseline = baseline_from_tests(
        earlier + measured, written_at=datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
        station=args.station or default_station(), software=f"edc-bench {__version__}",
        command=shlex.join(["edc-bench", *sys.argv[1:]]))
    text = baseline.to_toml(variant.name, f"{len(earlier)} earlier and {len(measured)} new tests"
                            if args.append else "")
    print(text, end="")
    print(f"baseline of {variant.name}: af0 {baseline.af_v:.5f} V, a1_0 {baseline.a1_v_s_per_mm:.6f} V s/mm, "
          f"{baseline_line(baseline.summary())}", file=sys.stderr)
    records = [t.record for t in baseline.test_list if t.record]
    if records:
        print("records behind it:\n" + "\n".join(f"  {r}" for r in records), file=sys.stderr)
    if baseline.tests < RECOMMENDED_TESTS:
        again = _next_valve_command(sys.argv[1:])
        print(f"edc-bench calibrate: note: {baseline.tests} test(s) so far; new valves differ by several per cent, "
              f"so calibrate at least {RECOMMENDED_TESTS} valves: mount the next new valve and run: {again}",
              file=sys.stderr)
    for line in pump_lines(variant, baseline):
        print(f"edc-bench calibrate: {line}", file=sys.stderr)
    if target is not None:
        kept = write_baseline(target, text)
        print(f"baseline of {variant.name} written to {target}" + (f" (the earlier one kept as {kept})" if kept
                                                                    else ""), file=sys.stderr)


def pump_lines(variant: Any, baseline: Any) -> list[str]:
    """What the baseline holds of the pumps its valves ran in, and what that lets the part diagnosis judge.

    A baseline's a0 and b are its pumps' return springs; a test's pump may differ by the type's tolerance
    (:func:`~edc_bench.verdict.part.pump_allowance`). With three or more pumps named, the spread between them is
    measured and held against the tolerance the variant states.
    """
    from edc_bench.verdict.baseline import RECOMMENDED_PUMPS
    from edc_bench.verdict.part import linearity_allowance_mm

    rack = variant.rack
    pumps = baseline.pumps
    stated = (f"the pump type's spring tolerance (spring rate +/-{rack.spring_tolerance_rel:.0%}, preload "
              f"+/-{rack.preload_tolerance_rel:.0%}, [rack] in the variant)")
    judged = linearity_allowance_mm(variant, pumps)
    if pumps == 0:
        return [f"the baseline's valves ran in simulated pumps, on the type's own spring: a pump tested against it "
                f"may differ within {stated}, and the rack-travel sensor's linearity is judged to {judged:.2f} mm"]
    if pumps is None or pumps < RECOMMENDED_PUMPS:
        which = "pumps not named (--pump-serial)" if pumps is None else f"{pumps} pump(s)"
        finer = linearity_allowance_mm(variant, RECOMMENDED_PUMPS)
        again = _next_valve_command(sys.argv[1:])
        return [f"note: the baseline's valves ran in {which}: its spring is that pump's, which may lie anywhere "
                f"within {stated}, so the rack-travel sensor's linearity is judged to {judged:.2f} mm; with new "
                f"valves in {RECOMMENDED_PUMPS} or more pumps of the type it is judged to {finer:.2f} mm: mount a "
                f"new valve in another pump and run: {again} --pump-serial SERIAL"]
    spread = _pump_spread(baseline)
    lines = [f"the baseline's valves ran in {pumps} pumps; between them the spring rate a0 spreads "
             f"{spread[0]:.1%} and the preload term b {spread[1]:.1%} (standard deviation); the sensor's linearity "
             f"is judged to {judged:.2f} mm"]
    # a uniform spread within +/-t has a standard deviation of t / sqrt(3): beyond twice that the stated tolerance is
    # not what these pumps hold
    net = rack.spring_n_per_mm - variant.coil.magnetic_stiffness_n_per_mm
    spring_sd = rack.spring_tolerance_rel * rack.spring_n_per_mm / net / math.sqrt(3.0)
    for name, measured, stated_sd, key in (("spring rate", spread[0], spring_sd, "spring_tolerance_rel"),
                                           ("preload", spread[1], rack.preload_tolerance_rel / math.sqrt(3.0),
                                            "preload_tolerance_rel")):
        if measured > 2.0 * stated_sd:
            lines.append(f"warning: the pumps' {name} spreads more than {stated} allows: check those pumps' return "
                         f"springs, or state the type's tolerance ([rack] {key}) as its spring's data sheet gives "
                         "it")
    return lines


def _pump_spread(baseline: Any) -> tuple[float, float]:
    """The spread between the baseline's pumps of a0 over a2 (the spring rate, the reading's scale taken out) and of
    b (relative standard deviations of the pumps' means)."""
    import numpy as np

    by_pump: dict[str, list[Any]] = {}
    for test in baseline.test_list:
        if None not in (test.a2_v_s2_per_mm, test.a0_v_per_mm, test.b_v):
            by_pump.setdefault(test.pump_serial or "simulated", []).append(test)
    means = np.array([[np.mean([t.a0_v_per_mm / t.a2_v_s2_per_mm for t in tests]), np.mean([t.b_v for t in tests])]
                      for tests in by_pump.values()])
    if len(means) < 2:
        return math.nan, math.nan
    spread = np.std(means, axis=0, ddof=1) / np.abs(np.mean(means, axis=0))
    return float(spread[0]), float(spread[1])


def _refuse_worn_valve(spec: str, variant: Any) -> None:
    """A baseline is of new valves: refuse a simulated valve worn beyond the variant's clearance spec."""
    from edc_bench.errors import ConfigError
    from edc_bench.physics.valve import parse_valve_spec

    valve = parse_valve_spec(spec, variant)
    if valve.clearance_mm > variant.valve.clearance_spec_mm or valve.roughness != 1.0:
        raise ConfigError(f"--valve {spec}: not a new valve (clearance {valve.clearance_mm:g} mm, spec "
                          f"{variant.valve.clearance_spec_mm:g} mm, roughness {valve.roughness:g}); a baseline is "
                          "measured on new valves: use --valve new")


def _check_writable(target: Path) -> None:
    """Refuse a baseline target that cannot be written: a folder, or a folder that cannot be made or written."""
    from edc_bench.cli.common import probe_writable
    from edc_bench.errors import ConfigError

    if target.is_dir():
        raise ConfigError(f"--baseline-file {target}: is a folder; give a file such as {target / 'baseline.toml'}")
    if target.exists() and not target.is_file():
        raise ConfigError(f"--baseline-file {target}: is a device or other special file; give a .toml file")
    folder = target.parent
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ConfigError(f"{target}: cannot make its folder ({exc.strerror or exc}); give a writable place "
                          "with --baseline-file FILE") from None
    probe_writable(folder, f"{target}: its folder {folder} is not writable; give a writable place with "
                            "--baseline-file FILE")


def _next_valve_command(argv: list[str]) -> str:
    """This run's command for the next valve: with --append, without this valve's --valve-id or --seed."""
    import shlex

    words, skip = [], False
    for word in argv:
        if skip:
            skip = False
            continue
        if word in ("--valve-id", "--seed"):
            skip = True
            continue
        if word != "--write" and not word.startswith(("--valve-id=", "--seed=")):
            words.append(word)
    return shlex.join(["edc-bench", *words, *([] if "--append" in words else ["--append"])])


def _rig_tests(args: argparse.Namespace, config: BusSettings, variant: Any, tests: int) -> list[Any]:
    """Real-time tests on the rig's mounted valve, on the bus ``config`` (checked: :func:`bus_settings`)."""
    from edc_bench.bench import BenchOptions, run_bench_test
    from edc_bench.protocol import default_icd
    from edc_bench.runtime.bus import ClosingBus, open_bus
    from edc_bench.runtime.clock import RealTimeClock
    from edc_bench.runtime.signals import stop_requested

    out = []
    with ClosingBus(open_bus(config, default_icd().bitrate)) as bus:  # a dead connection must not cost the baseline
        for n in range(tests):
            result = run_bench_test(bus, RealTimeClock(), variant, BenchOptions(
                valve_id=args.valve_id or "calibration", identity=_identity(args), classify=False))
            out.extend(_keep(args, result, n, tests, BaselineSource.RIG))
            if stop_requested():  # Ctrl-C ended this test (INVALID, recorded): run no more
                raise KeyboardInterrupt
    return out


def _simulated_rig_tests(args: argparse.Namespace, variant: Any, tests: int, seed: int) -> list[Any]:
    """Full-loop tests of one simulated valve on the simulated rig, in simulated time."""
    from edc_bench.bench import run_simulated_test
    from edc_bench.physics.valve import parse_valve_spec
    from edc_bench.runtime.signals import stop_requested

    valve = parse_valve_spec(args.valve, variant)
    out = []
    for n in range(tests):
        result = run_simulated_test(variant, valve, seed + n, valve_id=args.valve_id or f"{args.valve} (simulated)",
                                    identity=_identity(args), classify=False)
        out.extend(_keep(args, result, n, tests, BaselineSource.SIMULATED_RIG))
        if stop_requested():
            raise KeyboardInterrupt
    return out


def _identity(args: argparse.Namespace) -> Identity:
    """Who and where, for a calibration test's record."""
    from edc_bench.records.schema import Identity
    from edc_bench.station_settings import default_station

    from edc_bench.station_settings import station_identity

    return Identity(station=args.station or default_station(), pump_serial=args.pump_serial or "",
                    station_shown=station_identity().for_customers(args.station), purpose="calibration")


def _keep(args: argparse.Namespace, result: Any, n: int, tests: int, source: BaselineSource) -> list[Any]:
    """Write the test's record and print its line; the test as a baseline entry if it converged."""

    from edc_bench.errors import RecordNotWrittenError
    from edc_bench.records.record import missing_files, write_record
    from edc_bench.verdict.baseline import BaselineTest
    from edc_bench.verdict.verdicts import Verdict

    try:
        record = write_record(result, args.out, figure=False)
        missing = missing_files(record)
    except OSError as exc:  # the baseline names each test's record: without it, no baseline
        raise RecordNotWrittenError(f"the record of test {n + 1}/{tests} could not be written under {args.out} "
                                    f"({type(exc).__name__}: {exc}); no baseline was written: free space or give "
                                    "another --out, then calibrate again") from None
    if missing:  # nor with a record that lacks its data (a full disk part way)
        raise RecordNotWrittenError(f"the record of test {n + 1}/{tests} in {record} is incomplete ("
                                    + "; ".join(f"{k}: {v}" for k, v in missing.items())
                                    + "); no baseline was written: free space or give another --out, then calibrate "
                                      "again")
    head = f"test {n + 1}/{tests}"
    if result.verdict != Verdict.UNCLASSIFIED:  # INVALID, or a coil out of spec (FAIL): not a new valve's figures
        print(f"{head}: {result.verdict}, not used: {'; '.join(result.reasons)} (record {record})", file=sys.stderr)
        return []
    af, a1 = result.features.af, result.features.a1
    print(f"{head}: af {af:.5f} V, a1 {a1:.6f} V s/mm (record {record})", file=sys.stderr)
    return [BaselineTest(af, a1, result.valve_id, source, result.started_at, str(record.resolve()),
                         **kept_figures(result), pump_serial=args.pump_serial or "")]


def kept_figures(result: Any) -> dict[str, float | None]:
    """What a baseline keeps of one new-valve test besides af and a1: its standard errors, core shifts and repeating
    residual, and its a2, a0 and b (:class:`~edc_bench.verdict.baseline.BaselineTest`'s optional fields)."""
    return {**_uncertainty(result.identification), **_motion(result.judgement)}


def _motion(judgement: Any) -> dict[str, float | None]:
    """A test's a2, a0 and b referred to the reference coil, as the baseline keeps them (None where not estimated)."""
    from edc_bench.verdict.baseline import MOTION_KEYS, MOTION_PARAMETERS

    out: dict[str, float | None] = {}
    for key in MOTION_KEYS:
        estimate = judgement.parameters.get(MOTION_PARAMETERS[key])
        good = estimate is not None and estimate.estimated and math.isfinite(estimate.value)
        out[key] = float(estimate.value) if good else None
    return out


def _uncertainty(identification: Any) -> dict[str, float | None]:
    """A test's relative standard errors and core shifts of af and a1, and its repeating residual, for the
    baseline's own uncertainty (None where the identification has none)."""
    out: dict[str, float | None] = {}
    if identification is None:
        return out
    shifts = identification.model_fit.core_shift_rel if identification.model_fit is not None else None
    for name in ("af", "a1"):
        value, std = identification.final.get(name), identification.std.get(name)
        se = abs(std / value) if value and std is not None else math.nan
        out[f"{name}_se_rel"] = se if math.isfinite(se) else None
        shift = (shifts or {}).get(name)
        out[f"{name}_core_shift_rel"] = shift if shift is not None and math.isfinite(shift) else None
    systematic = identification.model_fit.systematic_rms_v if identification.model_fit is not None else math.nan
    out["systematic_rms_v"] = systematic if math.isfinite(systematic) else None
    return out
