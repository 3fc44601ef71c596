"""``edc-bench train``: build the valve classifiers from a simulated population."""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

DEFAULT_VARIANTS = ("p-edc-default", "p-edc-long")
DEFAULT_COUNT = 1000
DEFAULT_SEED = 2026


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Register the command."""
    p = sub.add_parser(
        "train", help="train and export the valve classifiers (needs the 'train' extra)",
        description="Simulate a population of used valves per variant through the batch path, label each valve "
                    "from its physics (the variant's resisting-force limit), and train the paper's network "
                    "(valve_mlp.onnx) and a linear model (valve_linear.onnx) on (af/af0, a1/a1_0). With the "
                    "defaults this rebuilds the models shipped in the package byte for byte.",
    )
    p.add_argument("--variants", nargs="+", default=list(DEFAULT_VARIANTS), metavar="NAME",
                   help=f"variants to draw populations from (default: {' '.join(DEFAULT_VARIANTS)})")
    p.add_argument("--count", type=int, default=DEFAULT_COUNT, help=f"valves per variant (default: {DEFAULT_COUNT})")
    p.add_argument("--seed", type=int, default=DEFAULT_SEED, help=f"seed of data and weights (default: {DEFAULT_SEED})")
    p.add_argument("--marginal-band", type=float, default=0.03,
                   help="half-width of the MARGINAL band around the boundary, in baseline ratios (default: 0.03)")
    p.add_argument("--dataset", type=Path, default=None, help="train on this dataset file instead of simulating")
    p.add_argument("--save-dataset", type=Path, default=None, help="also write the simulated dataset here")
    p.add_argument("--out-dir", type=Path, default=None,
                   help="where to write the models (default: the package's models folder)")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    """Simulate (or load) the data, train both models, write them."""
    from edc_bench.diagnosis.classifier import DEFAULT_MODEL, LINEAR_MODEL, packaged_model_path
    from edc_bench.diagnosis.dataset import Dataset, make_dataset
    from edc_bench.errors import ConfigError

    try:
        import sklearn  # noqa: F401

        from edc_bench.diagnosis.train import train
    except ImportError:
        raise ConfigError("training needs the 'train' extra: pip install '.[train]'") from None
    if args.count < 20:
        raise ConfigError(f"--count {args.count}: train on at least 20 valves per variant")
    if args.dataset is not None:
        dataset = Dataset.load(args.dataset)
    else:
        start = time.perf_counter()
        dataset = make_dataset(args.variants, args.count, args.seed)
        elapsed = time.perf_counter() - start
        print(f"simulated {len(dataset)} bench tests in {elapsed:.1f} s ({len(dataset) / elapsed * 60:.0f} per minute)",
              file=sys.stderr)
        if args.save_dataset is not None:
            dataset.save(args.save_dataset)
    out_dir = args.out_dir or packaged_model_path().parent
    out_dir.mkdir(parents=True, exist_ok=True)
    for kind, name in (("mlp", DEFAULT_MODEL), ("linear", LINEAR_MODEL)):
        model = train(dataset, kind, args.seed, marginal_band=args.marginal_band)
        (out_dir / name).write_bytes(model.onnx_bytes)
        print(f"{kind}: training accuracy {model.train_accuracy:.4f} on {len(dataset)} tests -> {out_dir / name}")
    print(f"training data sha256 {dataset.content_hash()}")
    return 0
