"""``edc-bench session``: a shift at the bench, full screen (edc_bench.session)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from edc_bench.cli.common import (
    add_bus_arguments,
    add_history_db_argument,
    add_pump_fault_arguments,
    add_rig_drift_argument,
    given_path,
    identity,
    seed_number,
)
from edc_bench.cli.exit_codes import ExitCode


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Register the command."""
    p = sub.add_parser(
        "session",
        help="a shift at the bench, full screen: scan, mount, test, verdict with what to do, report",
        description="A full-screen session for a shift: it asks the operator's name once (remembered for this "
                    "station), checks the rig with its reference valve, then for each valve asks, always in this "
                    "order, the valve id, the pump serial and 'mount the valve, then Enter' (a barcode scanner "
                    "types and ends with Enter); it tests the valve, retests a MARGINAL, shows the verdict with "
                    "what to do until the next scan, and makes the report (PDF and PNG) in every record. A pump "
                    "part number scanned at any prompt switches the pump type. Ctrl+Q twice ends the shift and writes "
                    "its summary. Without bus arguments the simulated rig runs in process (a valve id that names "
                    "a simulated valve, such as worn or clearance=0.185, gets that valve; any other id a used "
                    "valve drawn from it). 'edc-bench test' stays for scripts.",
    )
    p.add_argument("--variant", default=None, metavar="NAME|PART|PATH",
                   help="the pump type tested until a part number is scanned (default: p-edc-default)")
    add_bus_arguments(p, interface_help="python-can interface of a real rig, e.g. slcan, socketcan",
                      channel_help="python-can channel, e.g. can0 or socket://127.0.0.1:5000")
    p.add_argument("--seed", type=seed_number, default=0,
                   help="simulated rig: the first test's noise seed; each later test takes the next (default: 0)")
    p.add_argument("--out", type=given_path, default=Path("records"), metavar="DIR",
                   help="folder for record folders and the shift summary (default: ./records)")
    p.add_argument("--station", type=identity(), default=None, help="this bench station's name (default: host name)")
    p.add_argument("--operator", type=identity(), default=None,
                   help="who works the shift (default: the name given at this station last time; asked if none)")
    add_rig_drift_argument(p)
    add_pump_fault_arguments(p)
    add_history_db_argument(p)
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    """Run the session; print the shift's summary when it ends."""
    from edc_bench.station_settings import default_station, workshop_asked

    from edc_bench.cli.common import bus_settings, check_history_url, check_output_folder
    from edc_bench.config import load_variant
    from edc_bench.session.build import make_app
    from edc_bench.session.operator import remembered_operator
    from edc_bench.session.runner import RigChoice

    check_output_folder(args.out, "--out")
    check_history_url(args.db)
    load_variant(args.variant)  # a bad --variant is refused before the screen opens
    if not sys.stdin.isatty() or not sys.stdout.isatty():
        print("edc-bench session: needs a terminal (it is a full-screen app); for scripts use 'edc-bench test'",
              file=sys.stderr)
        return ExitCode.BAD_INPUT
    from edc_bench.errors import ConfigError, RigError

    try:
        bus_config = bus_settings(args.interface, args.channel, args.bitrate, configured_alone=True,
                                  options=args.bus_options)
    except RigError as exc:  # before the screen opens nothing has started: refused as input, the session's exit 2
        raise ConfigError(str(exc)) from None
    simulated_only = [flag for flag, value in (("--rig-drift", args.rig_drift), ("--rack-fault", args.rack_fault),
                                               ("--sensor-fault", args.sensor_fault)) if value is not None]
    if bus_config is not None and simulated_only:
        raise ConfigError(f"{', '.join(simulated_only)} describe{'s' if len(simulated_only) == 1 else ''} the "
                          "simulated rig: leave it out on a bus")
    rig = RigChoice(bus_config=bus_config, first_seed=args.seed, rig_drift=args.rig_drift,
                    rack_fault=args.rack_fault, sensor_fault=args.sensor_fault)
    app = make_app(args.variant, rig, args.out, args.db,
                   args.station or default_station(), args.operator or remembered_operator(),
                   ask_workshop=not workshop_asked(), station_given=args.station)
    from edc_bench.runtime.signals import interrupt_guard, stop_requested

    # Ctrl-C or SIGTERM sent to the session (kill, a shutdown) is held back: a test running ends as an abort (SAFE,
    # its record and history row kept), then the app ends the shift itself, and the terminal is left as it was
    with interrupt_guard(reraise=False):
        app.run()
        interrupted = stop_requested()
    for line in app.shift.summary_lines():
        print(line)
    if app.summary_file is not None:
        print(f"shift summary: {app.summary_file}")
    if interrupted:
        print("edc-bench session: interrupted (Ctrl-C or SIGTERM); every test started has its record", file=sys.stderr)
        return ExitCode.INTERRUPTED
    return ExitCode.OK
