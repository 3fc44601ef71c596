"""``edc-bench rig``: serve the simulated rig over slcan in real time."""

from __future__ import annotations

import argparse
import signal
import sys

from edc_bench.cli.common import add_variant_arguments, parse_host_port


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
    p.add_argument("--seed", type=int, default=0, help="seed of the sensor noise (default: 0)")
    p.add_argument("--adapter", default="none", metavar="SPEC",
                   help="hold frames back as a CAN adapter would: usb-fs (a USB full-speed adapter, 1.5-3.5 ms "
                        "round trip), or latency_ms=L,jitter_ms=J,usb_frame_ms=F one way[,drift_ppm=D] (default: none)")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    """Build the rig and serve until SIGINT or SIGTERM."""
    from edc_bench.config import load_variant
    from edc_bench.physics.valve import parse_valve_spec
    from edc_bench.sim.adapter import parse_adapter
    from edc_bench.sim.rig import SimulatedRig
    from edc_bench.sim.server import SlcanRigServer

    variant = load_variant(args.variant)
    valve = parse_valve_spec(args.valve, variant)
    adapter = parse_adapter(args.adapter)
    rig = SimulatedRig(variant, valve, seed=args.seed)
    server = SlcanRigServer(rig, log=lambda line: print(f"rig: {line}", flush=True), adapter=adapter)
    if args.pty:
        where = server.open_pty()
    else:
        host, port = server.listen_tcp(*args.listen)
        if host not in ("127.0.0.1", "::1", "localhost"):
            print(f"rig: warning: listening on {host}, not loopback", file=sys.stderr)
        where = f"socket://{host}:{port}"
    signal.signal(signal.SIGTERM, lambda *_: server.stop())
    signal.signal(signal.SIGINT, lambda *_: server.stop())
    print(f"rig: variant {variant.name}, valve {args.valve}, adapter {adapter.name}, serving slcan at {where}",
          flush=True)
    server.serve_forever()
    # the longest the rig went without serving while a host was connected: a test can tell a disturbed rig
    print(f"rig: stopped; worst serve gap {server.worst_gap_s * 1e3:.2f} ms", flush=True)
    return 0
