"""``edc-bench rig-selfcheck``: does the rig still measure as it did? A reference valve against its registration."""

from __future__ import annotations

import argparse
import json
import sys
from typing import TYPE_CHECKING, Any

from edc_bench.cli.exit_codes import ExitCode
from edc_bench.timefmt import local_text

if TYPE_CHECKING:
    from edc_bench.history.rows import ReferenceRow, RigCheckRow


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Register the command."""
    from edc_bench.cli.common import (
        add_bus_arguments,
        add_history_db_argument,
        add_rig_drift_argument,
        add_variant_arguments,
        identity,
        seed_number,
    )

    p = sub.add_parser(
        "rig-selfcheck", help="run the reference valve and compare with its registration: GO / NO-GO, what drifted",
        description="The rig checks itself with a reference valve kept at the bench: it reads the rig at rest (the "
                    "LVDT's zero, the current sensor's zero), tests the reference valve, and compares the coil's "
                    "resistance, the spring rate, af and a1 with the figures stored when the valve was registered. "
                    "GO, or NO-GO naming what drifted and what to do; every check goes into the history ('edc-bench "
                    "history --rig' shows the ledger). Register the valve first with --register --valve-id ID. "
                    "Without --interface/--channel it runs on the simulated rig in simulated time (--rig-drift: "
                    "its sensors drifted).",
    )
    p.add_argument("--register", action="store_true",
                   help="measure the reference valve now and store its figures for this station (replaces an "
                        "earlier registration; the ledger keeps both): an engineer's login on a shop's history")
    p.add_argument("--valve-id", type=identity(), default=None, metavar="ID",
                   help="with --register: the reference valve's id, as marked on it")
    add_variant_arguments(p)
    p.add_argument("--seed", type=seed_number, default=None,
                   help="simulated rig: the sensor noise's seed (default: 0 to register; then one more for each "
                        "check, as every day's noise is new)")
    add_rig_drift_argument(p)
    p.add_argument("--firmware", choices=("python", "c"), default="python",
                   help="simulated rig: its firmware, python (the prototype, default) or c (the C core)")
    add_bus_arguments(p, interface_help="python-can interface of a rig, e.g. slcan, socketcan, pcan")
    p.add_argument("--coil-temp-c", type=_coil_temp, default=None, metavar="C",
                   help="the reference valve's coil temperature (default: 20, a coil that has rested)")
    p.add_argument("--station", type=identity(), default=None,
                   help="this bench station's name (default: the host name)")
    p.add_argument("--by", type=identity(), default=None, metavar="NAME",
                   help="who runs the check or registers (default: the login name)")
    add_history_db_argument(p)
    p.add_argument("--json", action="store_true", help="print only JSON")
    p.set_defaults(run=run)


def _coil_temp(text: str) -> float:
    from edc_bench.cli.test_cmd import _coil_temp as parse

    return parse(text)


def _station(args: argparse.Namespace, store: Any) -> str:
    """The station's name as its history knows it: on a chain, the station its database login is mapped to (the
    name the database writes into its rows), else ``--station``, else the name the chain knows this PC's own login
    by, else the host name."""
    from edc_bench.station_settings import default_station

    from edc_bench.history.chain_adoption import chain_station

    if store.station:
        return str(store.station)
    return args.station or chain_station(store, default_station())


def run(args: argparse.Namespace) -> int:
    """Register the reference valve, or check the rig against it."""
    from edc_bench.cli.common import bus_settings, check_history_url, person_name
    from edc_bench.errors import ConfigError
    from edc_bench.selfcheck import Rig

    check_history_url(args.db)
    bus = bus_settings(args.interface, args.channel, args.bitrate, configured_alone=False, options=args.bus_options)
    simulated_only = [flag for flag, given in (("--rig-drift", args.rig_drift is not None),
                                               ("--seed", args.seed is not None),
                                               ("--firmware", args.firmware != "python")) if given]
    if bus is not None and simulated_only:
        raise ConfigError(f"{', '.join(simulated_only)} describe the simulated rig: leave them out on a bus")
    if args.register and not args.valve_id:
        raise ConfigError("--register needs --valve-id ID: the reference valve's id, as marked on it (e.g. "
                          "--valve-id REF-1)")
    if not args.register and args.valve_id:
        raise ConfigError("--valve-id goes with --register; a check runs the station's registered reference valve")
    if args.firmware == "c" and bus is None:
        from firmware_proto.c_firmware import CFirmwareMissing, load_library

        try:
            load_library()
        except CFirmwareMissing as exc:
            raise ConfigError(str(exc)) from None
    by = person_name(args.by, "who runs the check")
    rig = Rig(bus=bus, drift=args.rig_drift, firmware=args.firmware)
    return _register(args, rig, by) if args.register else _check(args, rig, by)


def _register(args: argparse.Namespace, rig: Any, by: str) -> int:
    from edc_bench.config import load_variant
    from edc_bench.history.store import HistoryStore
    from edc_bench.physics.valve import parse_valve_spec
    from edc_bench.selfcheck import measure_reference, registration_row

    variant = load_variant(args.variant)
    if rig.simulated:
        parse_valve_spec(args.valve, variant)  # before any work
    seed = args.seed if args.seed is not None else 0
    with HistoryStore(args.db) as store:
        station = _station(args, store)
        earlier = store.reference(station)
        _say(args, f"edc-bench rig-selfcheck: registering reference valve {args.valve_id} for station {station} on "
                   f"the {rig.describe()} (about {variant.excitation.duration_s + 0.5:g} s of rig time)")
        values = measure_reference(rig, variant, valve=args.valve, seed=seed, valve_id=args.valve_id,
                                   coil_temp_c=args.coil_temp_c, observer=_observer(args, rig))
        if values.test_problems or values.signal_faults:
            from edc_bench.errors import ConfigError

            raise ConfigError("the reference valve's test was not trustworthy, nothing was registered: "
                              + "; ".join(values.test_problems + tuple(f"the LVDT's signal: {fault}" for fault in
                                                                        values.signal_faults)))
        details = {"rig": rig.describe(), **({"seed": seed} if rig.simulated else {})}
        row = store.add_reference(registration_row(
            values, station=station, valve_id=args.valve_id, variant=variant.name, by=by, simulated=rig.simulated,
            valve_spec=args.valve if rig.simulated else None, details=details))
    notes = []
    if earlier is not None:
        notes.append(f"it replaces the registration of {local_text(earlier.registered_at)} (valve "
                     f"{earlier.valve_id}); the ledger keeps both")
    if values.lvdt_at_floor:
        notes.append("the LVDT reads 0 mm or less at rest, the least the rig reports: a zero that moves down "
                     "cannot be seen; set the LVDT's zero a little above 0 (e.g. 0.01 mm) and register again")
    if args.json:
        print(json.dumps({"registered": _jsonable(row), "notes": notes}, indent=2))
        return ExitCode.OK
    print(f"registered reference valve {args.valve_id} for station {station} (variant {variant.name}): "
          + ", ".join(f"{label} {_value(name, getattr(values, name))}" for name, label in _LABELS.items()))
    for note in notes:
        print(f"note: {note}")
    print("every 'edc-bench rig-selfcheck' at this station compares with these figures")
    return ExitCode.OK


def _check(args: argparse.Namespace, rig: Any, by: str) -> int:
    from edc_bench.config import load_variant
    from edc_bench.errors import ConfigError
    from edc_bench.history.store import HistoryStore
    from edc_bench.selfcheck import MEASURED, Registration, no_reference_line, rig_check_row, run_selfcheck

    with HistoryStore(args.db) as store:
        station = _station(args, store)
        registration = Registration.of(store.reference(station))
        if registration is None:
            print(no_reference_line(station), file=sys.stderr)
            return ExitCode.NO_REFERENCE_VALVE
        variant = load_variant(args.variant or registration.variant)
        if variant.name != registration.variant:
            raise ConfigError(f"--variant {args.variant}: the reference valve {registration.valve_id} is registered "
                              f"as variant {registration.variant}; leave out --variant, or register it again")
        if rig.simulated != registration.simulated:
            where = "the simulated rig" if registration.simulated else "a rig's bus"
            raise ConfigError(f"the reference valve {registration.valve_id} of station {station} was registered on "
                              f"{where}: check it there (or register it again on this one)")
        valve = args.valve if rig.simulated and args.valve != "new" else None  # a simulated valve swapped in
        seed = args.seed
        if seed is None:  # a new day's noise: one more than the last check's, counted from the registration's
            measured = [r for r in store.rig_checks(station, registration.id) if r.verdict in MEASURED]
            seed = (registration.seed or 0) + 1 + len(measured)  # a skip measured nothing: no new noise
        _say(args, f"edc-bench rig-selfcheck: reference valve {registration.valve_id} ({registration.variant}) on the "
                   f"{rig.describe()}")
        check = run_selfcheck(rig, registration, variant, seed=seed, valve=valve, coil_temp_c=args.coil_temp_c,
                              observer=_observer(args, rig))
        row = store.add_rig_check(rig_check_row(check, station, by))
    if args.json:
        print(json.dumps(_check_json(check, row, station), indent=2))
    else:
        _print_check(check, row)
    return ExitCode.OK if check.result.go else ExitCode.RIG_DRIFTED


#: The figures in the technician's words, in the order printed.
_LABELS = {"lvdt_zero_mm": "LVDT zero", "current_zero_a": "current zero", "coil_r20_ohm": "coil at 20 degC",
           "a0_v_per_mm": "spring rate a0", "af_v": "af", "a1_v_s_per_mm": "a1"}
_UNITS = {"lvdt_zero_mm": ("mm", ".3f"), "current_zero_a": ("A", ".4f"), "coil_r20_ohm": ("ohm", ".4f"),
          "a0_v_per_mm": ("V/mm", ".5f"), "af_v": ("V", ".5f"), "a1_v_s_per_mm": ("V s/mm", ".6f")}


def _value(name: str, value: float) -> str:
    import math

    unit, fmt = _UNITS[name]
    return "-" if not math.isfinite(value) else f"{value:{fmt}} {unit}"


def _print_check(check: Any, row: RigCheckRow) -> None:
    from edc_bench.cli.common import print_quietly_if_closed

    def write() -> None:
        result, reg = check.result, check.registration
        print(result.line())
        print(f"reference valve {reg.valve_id} ({reg.variant}), registered {local_text(reg.registered_at)}; "
              f"check {row.id} at station {row.station}")
        print(f"  {'figure':<16}{'registered':>16}{'now':>16}{'change':>12}{'limit':>10}")
        for q in result.quantities:
            mark = " <- " + ("moved with the " + str(q.explained_by) if q.explained_by else "drifted") if q.out else ""
            print(f"  {_LABELS[q.name]:<16}{_value(q.name, q.registered):>16}{_value(q.name, q.measured):>16}"
                  f"{q.drift_text():>12}{q.limit_text():>10}{mark}")
        print("ledger: edc-bench history --rig")

    print_quietly_if_closed(write)


def _check_json(check: Any, row: RigCheckRow, station: str) -> dict[str, Any]:
    from edc_bench.records.writer import json_safe

    result, reg = check.result, check.registration
    return json_safe({
        "verdict": result.verdict, "line": result.line(), "causes": [str(c) for c in result.causes],
        "findings": [{"cause": str(f.cause), "words": f.words} for f in result.findings],
        "figures": {q.name: {"measured": q.measured, "registered": q.registered, "drift": q.drift,
                             "tolerance": q.tolerance, "relative": q.relative, "out": q.out, "compared": q.compared,
                             "explained_by": None if q.explained_by is None else str(q.explained_by)}
                    for q in result.quantities},
        "reference": {"id": reg.id, "valve_id": reg.valve_id, "variant": reg.variant,
                      "registered_at": reg.registered_at},
        "check_id": row.id, "station": station, **check.details,
    })


def _jsonable(row: ReferenceRow) -> dict[str, Any]:
    from edc_bench.records.writer import json_safe

    return json_safe({k: v for k, v in row.columns().items() if k not in ("details", "prev_hash", "row_hash")})


def _say(args: argparse.Namespace, line: str) -> None:
    if not args.json:
        print(line, file=sys.stderr, flush=True)


def _observer(args: argparse.Namespace, rig: Any) -> Any:
    """Log lines on stderr for a test on a rig (half a minute); nothing on the simulated rig (seconds) or with --json."""
    if args.json or rig.simulated:
        return None
    from edc_bench.ui.plain import PlainLog

    return PlainLog(sys.stderr)
