"""``edc-bench calibrate``: measure a variant's new-valve baseline (af0, a1_0)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Register the command."""
    p = sub.add_parser(
        "calibrate", help="measure a variant's new-valve baseline",
        description="Run N bench tests of new valves and write the variant's baseline (mean af and a1 with "
                    "their spread), against which features are expressed. Without bus arguments the valves are "
                    "simulated (each new valve with the variant's spread); with --interface/--channel the N tests "
                    "run on that rig in real time, on the valve mounted (calibrate valve by valve with --append).",
    )
    p.add_argument("--variant", default=None, metavar="NAME|PART|PATH", help="pump variant (default: p-edc-default)")
    p.add_argument("--tests", type=int, default=20, help="number of tests (default: 20)")
    p.add_argument("--seed", type=int, default=100, help="seed of the simulated valves (default: 100)")
    p.add_argument("--interface", default=None, help="python-can interface of a real rig")
    p.add_argument("--channel", default=None, help="python-can channel of a real rig")
    p.add_argument("--bitrate", type=int, default=None, help="CAN bit rate")
    p.add_argument("--write", action="store_true",
                   help="write baselines/<variant>.toml beside the variant's file in the library "
                        "(configs/ for shipped variants, the station's variant folder otherwise; default: print it)")
    p.add_argument("--out", type=Path, default=None, help="write the baseline to this file instead")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    """Calibrate and print or write the baseline."""
    from edc_bench.config import load_variant
    from edc_bench.config.loader import available_variants, station_variant_dir
    from edc_bench.diagnosis.baseline import BASELINE_DIR
    from edc_bench.diagnosis.calibrate import baseline_from_features, calibrate_simulated
    from edc_bench.errors import ConfigError

    if args.tests < 2:
        raise ConfigError(f"--tests {args.tests}: a baseline needs at least 2 tests")
    variant = load_variant(args.variant)
    if args.interface or args.channel:
        from edc_bench.bench import run_bench_test
        from edc_bench.diagnosis.verdict import Verdict
        from edc_bench.protocol import default_icd
        from edc_bench.runtime.bus import open_bus
        from edc_bench.runtime.clock import RealTimeClock

        config = {k: v for k, v in (("interface", args.interface), ("channel", args.channel),
                                    ("bitrate", args.bitrate)) if v is not None}
        af, a1 = [], []
        with open_bus(config, default_icd().bitrate) as bus:
            for n in range(args.tests):
                result = run_bench_test(bus, RealTimeClock(), variant, valve_id=f"calibration-{n}",
                                        classify=False)
                print(f"test {n + 1}/{args.tests}: {result.verdict} af={result.features['af']:.5f} "
                      f"a1={result.features['a1']:.6f}", file=sys.stderr)
                if result.verdict != Verdict.INVALID:
                    af.append(result.features["af"])
                    a1.append(result.features["a1"])
        baseline = baseline_from_features(af, a1, f"rig {config}: {len(af)} of {args.tests} tests")
    else:
        baseline = calibrate_simulated(variant, args.tests, args.seed)
    text = baseline.to_toml(variant.name, f"edc-bench calibrate --variant {variant.name} --tests {args.tests} "
                                          f"--seed {args.seed}")
    target = args.out
    if args.write and target is None:
        # beside the variant's file in the library: shipped variants in configs/, a station's in its folder
        library_file = available_variants().get(variant.name)
        folder = library_file.parent if library_file is not None else station_variant_dir()
        target = folder / BASELINE_DIR / f"{variant.name}.toml"
    if target is not None:
        target.parent.mkdir(parents=True, exist_ok=True)
        target.write_text(text, encoding="utf-8")
        print(f"baseline of {variant.name} written to {target}", file=sys.stderr)
    print(text, end="")
    return 0
