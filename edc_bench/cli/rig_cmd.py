"""``edc-bench rig``: serve the simulated rig over slcan in real time."""

from __future__ import annotations

import argparse
import contextlib
import signal
import sys

from edc_bench.cli.common import (
    add_pump_fault_arguments,
    add_rig_drift_argument,
    add_variant_arguments,
    parse_host_port,
    seed_number,
)


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Register the command."""
    p = sub.add_parser(
        "rig",
        help="run the simulated rig as a process serving slcan",
        description="Run the simulated pump rig in real time, serving the slcan protocol on a loopback TCP "
                    "port (--listen) or a pseudo-terminal (--pty). Drive it with any slcan host, e.g. "
                    "'edc-bench test --realtime --interface slcan --channel socket://127.0.0.1:PORT'.",
    )
    where = p.add_mutually_exclusive_group(required=True)
    where.add_argument("--listen", type=parse_host_port, metavar="HOST:PORT",
                       help="serve on this TCP address (port 0 picks a free port)")
    where.add_argument("--pty", action="store_true", help="serve on a new pseudo-terminal and print its path")
    add_variant_arguments(p)
    p.add_argument("--seed", type=seed_number, default=0, help="seed of the sensor noise (default: 0)")
    p.add_argument("--adapter", default="none", metavar="SPEC",
                   help="hold frames back as a CAN adapter would: usb-fs (a USB full-speed adapter, 1.5-3.5 ms "
                        "round trip), or latency_ms=L,jitter_ms=J,usb_frame_ms=F one way[,drift_ppm=D] (default: none)")
    p.add_argument("--firmware", choices=("python", "c"), default="python",
                   help="the rig's firmware: python (the prototype, default) or c (the C core, built on first "
                        "use into the user's cache: needs make and gcc)")
    add_rig_drift_argument(p)
    add_pump_fault_arguments(p)
    p.add_argument("--break", dest="breaks", action="append", default=[], metavar="RULE",
                   help="break this ICD rule, for trying 'edc-bench rig-check' on a rig that fails it (repeatable): "
                        "answers-bad-crc, wrong-counter-echo, slow-watchdog, no-watchdog, no-heartbeat, "
                        "slow-heartbeat, drives-after-safe, samples-after-drive")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    """Build the rig and serve until SIGINT or SIGTERM."""
    from edc_bench.config import load_variant
    from edc_bench.errors import ConfigError
    from edc_bench.physics.valve import parse_valve_spec
    from edc_bench.sim.adapter import parse_adapter
    from edc_bench.sim.rig import RigOptions, SimulatedRig
    from edc_bench.sim.server import SlcanRigServer

    if args.listen is not None:
        check_listen_address(*args.listen)  # before anything is built or started
    variant = load_variant(args.variant)
    valve = parse_valve_spec(args.valve, variant)
    adapter = parse_adapter(args.adapter)
    rig = SimulatedRig(variant, valve, seed=args.seed,
                       options=RigOptions(breaks=_breaks(args.breaks), firmware=args.firmware,
                                          drift=args.rig_drift or RigOptions().drift,
                                          rack_fault=args.rack_fault or RigOptions().rack_fault,
                                          sensor_fault=args.sensor_fault or RigOptions().sensor_fault))
    server = SlcanRigServer(rig, log=lambda line: print(f"rig: {line}", flush=True), adapter=adapter)
    if args.pty:
        where = server.open_pty()
    else:
        try:
            host, port = server.listen_tcp(*args.listen)
        except OSError as exc:  # taken since the check: the same message
            raise ConfigError(_listen_problem(args.listen, exc)) from None
        if host not in ("127.0.0.1", "::1", "localhost"):
            print(f"rig: warning: listening on {host}, not loopback", file=sys.stderr)
        where = f"socket://{host}:{port}"
    signal.signal(signal.SIGTERM, lambda *_: server.stop())
    signal.signal(signal.SIGINT, lambda *_: server.stop())
    broken = f", breaking {', '.join(args.breaks)}" if args.breaks else ""
    if args.rig_drift is not None and not args.rig_drift.none:
        broken += f", sensors drifted: {args.rig_drift.spec()}"
    for name, fault in (("rack", args.rack_fault), ("rack-travel sensor", args.sensor_fault)):
        if fault is not None and not fault.none:
            broken += f", pump's {name} faulty: {fault.spec()}"
    print(f"rig: variant {variant.name}, valve {args.valve}, adapter {adapter.name}, {args.firmware} firmware{broken}, "
          f"serving slcan at {where}", flush=True)
    from edc_bench.runtime.priority import BENCH_PRIORITY, how_to_allow, realtime_permitted, realtime_priority

    # the rig is the hardware's side: one above the bench's priority, as the rig process a test starts is (a rig
    # at normal priority beside a bench at real-time priority on one PC went unserved: "the rig stopped answering")
    with contextlib.ExitStack() as raised:
        priority = raised.enter_context(realtime_priority(BENCH_PRIORITY + 1))
        if not priority.realtime:  # a login allowed the bench's own priority (rtprio 50) and no more: that one
            priority = raised.enter_context(realtime_priority(BENCH_PRIORITY))
        print(f"rig: scheduling {priority.describe()}", flush=True)
        if not priority.realtime:
            print("rig: warning: a bench on this PC may find this rig late on a busy PC; "
                  f"{priority.how if realtime_permitted() else how_to_allow()}",
                  file=sys.stderr, flush=True)
        server.serve_forever()
    # the longest the rig went without serving while a host was connected: a test can tell a disturbed rig
    print(f"rig: stopped; worst serve gap {server.worst_gap_s * 1e3:.2f} ms", flush=True)
    return 0


def _breaks(names: list[str]) -> frozenset:
    """``--break`` names as ICD breaks; a ConfigError naming the choices for an unknown one."""
    from edc_bench.errors import ConfigError
    from edc_bench.sim.broken_rigs import IcdBreak

    try:
        return frozenset(IcdBreak.parse(name) for name in names)
    except ValueError as exc:
        raise ConfigError(f"--break: {exc}") from None


def check_listen_address(host: str, port: int) -> None:
    """Refuse ``--listen HOST:PORT`` that this machine cannot serve on: not its address, a port in use.

    Binds a throw-away socket there and closes it: the one test that asks the
    operating system itself (a name that does not resolve, an address of
    another machine, a port taken or not permitted).

    Raises
    ------
    ConfigError
        Naming the address, what is wrong and what to give instead.
    """
    import socket

    from edc_bench.errors import ConfigError

    try:
        socket.create_server((host, port)).close()
    except (OSError, OverflowError) as exc:
        raise ConfigError(_listen_problem((host, port), exc)) from None


def _listen_problem(address: tuple[str, int], exc: Exception) -> str:
    """Why ``--listen`` failed, in words, and what to give instead."""
    import errno
    import socket

    host, port = address
    code = getattr(exc, "errno", None)
    if isinstance(exc, socket.gaierror) or (code or 0) < 0:  # getaddrinfo's codes are negative
        why = f"{host!r} is not an address or a name this machine can resolve"
    elif code == errno.EADDRNOTAVAIL:
        why = f"{host} is not an address of this machine"
    elif code == errno.EADDRINUSE:
        why = f"port {port} is in use (another rig?); give another port, or 0 for any free one"
    elif code == errno.EACCES:
        why = f"port {port} needs privileges; give a port above 1023, or 0 for any free one"
    else:
        why = str(getattr(exc, "strerror", None) or exc)
    return (f"--listen {host}:{port}: {why}; e.g. --listen 127.0.0.1:5000 (this machine only) or the address of "
            "one of this machine's network interfaces")
