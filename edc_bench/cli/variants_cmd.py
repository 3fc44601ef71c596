"""``edc-bench variants``: list the pump variant library."""

from __future__ import annotations

import argparse


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Register the command."""
    p = sub.add_parser("variants", help="list pump variants", description="List the pump variants in the library.")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    """List variant names, part numbers and files."""
    import os
    from pathlib import Path

    from edc_bench.config import DEFAULT_VARIANT, available_variants, load_variant
    from edc_bench.errors import ConfigError

    configured = os.environ.get("EDC_BENCH_VARIANTS_DIR")
    if configured and Path(configured).exists() and not Path(configured).is_dir():
        raise ConfigError(f"EDC_BENCH_VARIANTS_DIR={configured}: is a file, not a folder; point it to the folder "
                          "of this station's variant files (or unset it)")
    for name, path in available_variants().items():
        try:
            variant = load_variant(path)
        except ConfigError as exc:  # one broken file must not hide the others
            print(f"{name:<20} {'?':<14} cannot be used: {exc}")
            continue
        mark = " (default)" if name == DEFAULT_VARIANT else ""
        print(f"{name:<20} {variant.pump.part_number:<14} {variant.pump.description}{mark}")
    from edc_bench.config.loader import station_variant_dir

    print(f"\nthis station's own variants go in {station_variant_dir()} (see docs/variants.md)")
    return 0
