"""``edc-bench train``: build the valve classifiers from a simulated population."""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Any

from edc_bench.cli.common import (
    MAX_POPULATION,
    add_hidden_alias,
    add_history_db_argument,
    add_include_simulated_argument,
    check_output_file,
    check_output_folder,
    count_up_to,
    given_path,
    given_path_text,
    identity,
    seed_number,
)

DEFAULT_VARIANTS = ("p-edc-default", "p-edc-long")
DEFAULT_COUNT = 1000
DEFAULT_SEED = 2026


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Register the command."""
    p = sub.add_parser(
        "train", help="train and export the valve classifiers (needs the 'train' extra)",
        description="Simulate a population of used valves per variant through the batch path, label each valve "
                    "from its physics (the variant's resisting-force limit), and train the paper's network "
                    "(valve_mlp.onnx) and a linear model (valve_linear.onnx) on (af/af0, a1/a1_0). They are "
                    "written into the station's models folder, never into the installed package: the pair as "
                    "candidates, which change nothing until one is adopted (--adopt FILE); with the defaults "
                    "they are the shipped models byte for byte. --rebuild-shipped writes the shipped models in "
                    "a source checkout (developers). --from-history trains a candidate on the shop's labelled "
                    "tests instead (teardown findings recorded with 'edc-bench label'), with that simulated "
                    "population as a prior, and prints its cross-validated accuracy beside the current model's; "
                    "--adopt makes a candidate the station's model. Too few labels are refused as bad input "
                    "(exit 2), with the counts.",
    )
    p.add_argument("--variants", nargs="+", default=list(DEFAULT_VARIANTS), metavar="NAME",
                   help=f"variants to draw populations from (default: {' '.join(DEFAULT_VARIANTS)})")
    p.add_argument("--count", type=count_up_to(MAX_POPULATION, " valves per variant (that many take hours)"),
                   default=DEFAULT_COUNT,
                   help=f"valves per variant (default: {DEFAULT_COUNT})")
    p.add_argument("--seed", type=seed_number, default=DEFAULT_SEED,
                   help=f"seed of data and weights (default: {DEFAULT_SEED})")
    p.add_argument("--marginal-band", type=float, default=0.03,
                   help="half-width of the MARGINAL band around the boundary, in baseline ratios (default: 0.03)")
    p.add_argument("--dataset", type=given_path, default=None, metavar="FILE",
                   help="train on this dataset file instead of simulating")
    p.add_argument("--save-dataset", type=given_path, default=None, metavar="FILE",
                   help="also write the simulated dataset to this file")
    p.add_argument("--own", action="store_true",
                   help="train one variant's own network (give one --variants name or file), for a pump whose "
                        "resisting force splits between friction and damping unlike the shipped network's pumps: "
                        "written into the station's models folder as the file its [diagnosis] model line names, "
                        "else valve_mlp-NAME.onnx (then add that line); a file the package ships is written as a "
                        "candidate instead, and the shipped one kept")
    p.add_argument("--models-dir", type=given_path, default=None, metavar="DIR",
                   help="folder to write the models into (default: the station's models folder; never the "
                        "package's)")
    add_hidden_alias(p, "--out-dir", "models_dir", type=given_path)  # its name before the flags were made consistent
    p.add_argument("--rebuild-shipped", action="store_true",
                   help="write the models into the package's source tree, as the shipped ones (developers: a "
                        "source checkout only, never an installed package)")
    shop = p.add_argument_group("the shop's data")
    shop.add_argument("--from-history", action="store_true",
                      help="train a candidate on the history's labelled tests, the simulated population as prior")
    add_history_db_argument(shop, "with --from-history, or --adopt (where the adoption is recorded): ")
    add_include_simulated_argument(shop)
    shop.add_argument("--prior-weight", type=float, default=None, metavar="TESTS",
                      help="how many labelled tests the whole simulated population counts as (default: 50; 0: the "
                           "labels alone)")
    shop.add_argument("--name", default=None, help="the candidate's name (default: shop- and its labels' hash)")
    shop.add_argument("--candidate-file", type=given_path, default=None, metavar="ONNX",
                      help="the file to write the candidate to (default: candidates/NAME.onnx in the station's "
                           "models folder)")
    add_hidden_alias(shop, "--out", "candidate_file", type=given_path)  # its name before --out meant a folder only
    shop.add_argument("--adopt", default=None, type=given_path_text, metavar="ONNX|shipped",
                      help="make this model the station's (a candidate file), or go back to the shipped network")
    shop.add_argument("--by", type=identity(), default=None, metavar="NAME",
                      help="with --adopt: who adopts (default: login name)")
    shop.add_argument("--json", action="store_true", help="with --from-history: print the figures as JSON")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    """Simulate (or load) the data, train both models (or a variant's own network), write them."""
    from edc_bench.errors import ConfigError

    if args.own and args.adopt is not None:
        raise ConfigError("--own trains a variant's own network; --adopt makes a candidate the station's model: "
                          "give one of them")
    if args.own and (args.from_history or len(args.variants) != 1):  # before seconds of importing scikit-learn
        raise ConfigError("--own trains one variant's own network from its simulated population: give one "
                          "--variants NAME, without --from-history")
    if args.rebuild_shipped:
        _check_rebuild(args)
    if args.adopt is not None:  # adopting needs no training extra
        return _adopt(args)
    from edc_bench.cli.common import require_extra

    require_extra("train", "training")
    if args.count < 20:
        raise ConfigError(f"--count {args.count}: train on at least 20 valves per variant")
    _check_training_inputs(args)
    if args.from_history:
        return _from_history(args)
    for flag, value in (("--db", args.db), ("--prior-weight", args.prior_weight), ("--name", args.name),
                        ("--candidate-file", args.candidate_file), ("--by", args.by), ("--json", args.json or None)):
        if value is not None:
            raise ConfigError(f"{flag} goes with --from-history or --adopt")
    return _from_simulation(args)


def _from_simulation(args: argparse.Namespace) -> int:
    """Train on a simulated population (or ``--dataset``) and write the models where :func:`_destination` says."""
    from edc_bench.learning.adoption import write_model
    from edc_bench.learning.dataset import Dataset, make_dataset
    from edc_bench.learning.train import train
    from edc_bench.runtime.signals import stop_if_interrupted
    from edc_bench.verdict.classifier import DEFAULT_MODEL, LINEAR_MODEL

    own = _own(args.variants[0]) if args.own else None
    out_dir, where = _destination(args, own)
    check_output_folder(out_dir, where)  # before minutes of simulation and training
    if args.dataset is not None:
        dataset = Dataset.load(args.dataset)
    else:
        start = time.perf_counter()
        dataset = make_dataset(args.variants, args.count, args.seed)
        elapsed = time.perf_counter() - start
        print(f"simulated {len(dataset)} bench tests in {elapsed:.1f} s ({len(dataset) / elapsed * 60:.0f} per minute)",
              file=sys.stderr)
        if args.save_dataset is not None:
            stop_if_interrupted()  # a population a library ran on after Ctrl-C is not kept
            dataset.save(args.save_dataset)
    # a variant's own: the network only (the shipped pair's linear model is a yardstick for the network)
    kinds = [("mlp", own[1])] if own else [("mlp", DEFAULT_MODEL), ("linear", LINEAR_MODEL)]
    written = []
    for kind, name in kinds:
        model = train(dataset, kind, args.seed, marginal_band=args.marginal_band)
        stop_if_interrupted()  # nor a model trained on after it
        if where == CANDIDATE:  # named for its data: never the shipped model's name, which it does not replace
            name = f"{Path(name).stem}-sim-{dataset.content_hash()[:8]}.onnx"
        kept = write_model(out_dir, name, model.onnx_bytes)
        written.append(out_dir / name)
        print(f"{kind}: training accuracy {model.train_accuracy:.4f} on {len(dataset)} tests -> {out_dir / name}")
        if kept is not None:
            print(f"kept the earlier {name} as {kept.name}: the tests it judged still replay with it")
    print(f"training data sha256 {dataset.content_hash()}")
    _say_what_changed(where, own, written[0])
    return 0


#: Where :func:`_destination` writes: a candidate to adopt, a station variant's own network, the source tree's
#: shipped models, the folder ``--models-dir`` names.
CANDIDATE, STATION, SHIPPED, FOLDER = ("the station's candidates folder", "the station's models folder",
                                       "--rebuild-shipped", "--models-dir")


def _destination(args: argparse.Namespace, own: tuple[Any, str] | None) -> tuple[Path, str]:
    """The folder the models are written into, and which of :data:`CANDIDATE`, ... it is.

    Never the installed package's: a file there is the same for every station and every record judged by it
    (``--models-dir`` inside it is refused by :func:`_check_training_inputs`). A variant's own network goes where
    its variant finds it (the station's models folder), unless the package ships that file: written there it would
    stand in for the shipped one unasked, so it is a candidate then, as the pair always is.
    """
    from edc_bench.paths import source_checkout
    from edc_bench.verdict.classifier import packaged_model_path, station_models_dir

    root = source_checkout() if args.rebuild_shipped else None
    if root is not None:  # else refused by _check_rebuild before
        return root / "edc_bench" / "verdict" / "models", SHIPPED
    if args.models_dir is not None:  # the station's own folder, named: where a variant finds its network
        station = args.models_dir.resolve() == station_models_dir().resolve()
        return args.models_dir, STATION if station and own is not None else FOLDER
    if own is not None and not packaged_model_path(own[1]).is_file():
        return station_models_dir(), STATION
    return station_models_dir() / "candidates", CANDIDATE


def _say_what_changed(where: str, own: tuple[Any, str] | None, written: Path) -> None:
    """One line on what the station judges with now, and the command that changes it."""
    import shlex

    from edc_bench.verdict.classifier import packaged_model_path, station_models_dir

    if where == CANDIDATE and own is None:
        print(f"not adopted: this station judges as before; to judge with this network: edc-bench train --adopt "
              f"{shlex.quote(str(written))}")
    elif where == CANDIDATE:
        print(f"{own[0].name} is judged by the shipped {own[1]} as before; to judge its valves by this network on "
              f"this station, train it into the station's models folder: --models-dir "
              f"{shlex.quote(str(station_models_dir()))} ('edc-bench train --adopt shipped' goes back)")
    elif where == STATION and own[0].diagnosis.model == own[1]:
        instead = (" instead of the shipped one ('edc-bench train --adopt shipped' goes back)"
                   if packaged_model_path(own[1]).is_file() else "")
        print(f"{own[0].name}'s valves are judged by it from now on (its [diagnosis] model line names "
              f"{own[1]}){instead}")
    elif where == STATION:
        print(f"to judge {own[0].name}'s valves by it, add  model = \"{own[1]}\"  to the [diagnosis] section of "
              f"{own[0].source_file or 'its variant file'}")
    elif where == SHIPPED:
        print(f"the shipped models in the source tree ({written.parent}) are rebuilt: they ship with the next build")


def _own(name: str) -> tuple[Any, str]:
    """The variant ``name`` and the file its own network is written to (:func:`_own_file`)."""
    from edc_bench.config import load_variant
    from edc_bench.verdict.classifier import own_model_file

    variant = load_variant(name)  # a name, part number or file: the variant's own name
    return variant, variant.diagnosis.model or own_model_file(variant.name)


def _own_file(name: str) -> str:
    """The file a variant's own network is written to: the one its ``[diagnosis] model`` line names, else
    ``valve_mlp-<variant name>.onnx`` (which that line then names)."""
    return _own(name)[1]


def _check_rebuild(args: argparse.Namespace) -> None:
    """``--rebuild-shipped``: a source checkout's shipped models, and nothing else at the same time."""
    from edc_bench.errors import ConfigError
    from edc_bench.paths import package_folders, source_checkout

    if args.adopt is not None or args.from_history:
        raise ConfigError("--rebuild-shipped rebuilds the shipped models from their simulated populations: leave "
                          "out --adopt and --from-history")
    if args.models_dir is not None:
        raise ConfigError("--rebuild-shipped writes the source tree's models folder, --models-dir another one: "
                          "give one of them")
    if source_checkout() is None:
        raise ConfigError(f"--rebuild-shipped: this edc-bench is an installed package ({package_folders()[0]}), "
                          "whose files the program never writes; run it in a source checkout (pip install -e .), "
                          "or give --models-dir DIR to build the models elsewhere")


def _check_training_inputs(args: argparse.Namespace) -> None:
    """Everything training reads or writes, checked before minutes of simulation and training."""
    import math

    from edc_bench.config import load_variant
    from edc_bench.errors import ConfigError
    from edc_bench.paths import inside_package

    if not (math.isfinite(args.marginal_band) and 0 <= args.marginal_band < 0.5):
        raise ConfigError(f"--marginal-band {args.marginal_band}: give the band's half-width in baseline ratios, "
                          "0 or more and below 0.5 (default 0.03)")
    if args.dataset is not None and not args.dataset.is_file():
        raise ConfigError(f"--dataset {args.dataset}: no such file; give a dataset written with --save-dataset")
    for flag, path in (("--models-dir", args.models_dir), ("--save-dataset", args.save_dataset),
                       ("--candidate-file", args.candidate_file)):
        if path is not None and inside_package(path):
            rebuild = ", or --rebuild-shipped in a source checkout" if flag == "--models-dir" else ""
            raise ConfigError(f"{flag} {path}: that is inside the installed edc-bench package, whose files the "
                              f"program never writes; give a folder of your own (default: the station's){rebuild}")
    if args.save_dataset is not None:
        check_output_file(args.save_dataset, "--save-dataset")
    if args.dataset is None or args.own:
        for name in args.variants:
            load_variant(name)


def _adopt(args: argparse.Namespace) -> int:
    import getpass
    from edc_bench.station_settings import default_station

    from edc_bench.errors import ConfigError
    from edc_bench.history.store import HistoryStore
    from edc_bench.learning.adoption import adopt, adopt_shipped, load_candidate
    from edc_bench.learning.candidate_evaluation import EVALUATION_KEY, CandidateEvaluation
    from edc_bench.verdict.classifier import packaged_model_path

    if args.from_history:
        raise ConfigError("--adopt and --from-history are separate steps: train, read the figures, then adopt")
    for flag, value in (("--prior-weight", args.prior_weight), ("--name", args.name),
                        ("--candidate-file", args.candidate_file), ("--json", args.json or None),
                        ("--dataset", args.dataset), ("--include-simulated", args.include_simulated or None),
                        ("--models-dir", args.models_dir), ("--save-dataset", args.save_dataset)):
        if value is not None:
            raise ConfigError(f"{flag} does not go with --adopt (it adopts a model file, or 'shipped')")
    from edc_bench.history.chain_adoption import chain_station, check_adoption_target

    check_adoption_target(args.db)  # a chain's station adopts in the chain, nowhere else
    shipped = args.adopt == "shipped"
    model = load_candidate(packaged_model_path() if shipped else Path(args.adopt))
    by = args.by or getpass.getuser()
    adopted: list[Any] = []
    # recorded in the history around the station's change: a login that may not adopt changes nothing here
    # a shop candidate carries its cross-validated figures: the history keeps what the adoption was decided on
    evaluation = CandidateEvaluation.from_json(model.metadata.get(EVALUATION_KEY))
    with HistoryStore(args.db) as store:
        store.add_adoption(model.name, model.sha256, chain_station(store, default_station()), by,
                           then=lambda: adopted.append(adopt_shipped() if shipped else adopt(Path(args.adopt), by,
                                                                                             model)),
                           evaluation=None if evaluation is None else evaluation.to_json())
        where = store.shown_url
    if shipped:
        # the files that stood in for shipped ones, renamed: named so the line says where they went
        aside = "".join(f"; {was.name} set aside as {now.name}, where the tests it judged still replay"
                        for was, now in adopted[0])
        print(f"this station judges with the shipped models again ({model.name}){aside}; recorded in {where}")
        return 0
    adoption = adopted[0]
    print(f"this station now judges with {adoption['name']} (sha256 {adoption['sha256'][:16]}...; a variant whose "
          f"file names its own network keeps it), adopted by "
          f"{adoption['adopted_by']}; every record names it; recorded in {where}. Go back with: edc-bench train "
          "--adopt shipped")
    return 0


def _from_history(args: argparse.Namespace) -> int:
    import json
    import math
    import re

    from edc_bench.errors import ConfigError
    from edc_bench.history.labels import labelled_tests
    from edc_bench.history.store import HistoryStore
    from edc_bench.learning.dataset import Dataset, cached_dataset
    from edc_bench.learning.shop_training import DEFAULT_PRIOR_WEIGHT, check_enough, train_from_labels
    from edc_bench.paths import atomic_write
    from edc_bench.runtime.signals import stop_if_interrupted
    from edc_bench.verdict.classifier import ValveClassifier, station_models_dir

    if args.candidate_file is not None:
        check_output_file(args.candidate_file, "--candidate-file")
    if args.name is not None and not re.fullmatch(r"[A-Za-z0-9._-]{1,100}", args.name):
        raise ConfigError(f"--name {args.name!r}: use letters, digits, '.', '_' and '-' (at most 100), e.g. shop-2026-11")
    if args.prior_weight is not None and not (math.isfinite(args.prior_weight) and args.prior_weight >= 0):
        raise ConfigError(f"--prior-weight {args.prior_weight}: give how many labelled tests the simulated "
                          "population counts as, 0 or more (default 50)")
    with HistoryStore(args.db, must_exist=True) as store:  # checked (check_url) before it is opened
        labelled = labelled_tests(store, args.include_simulated)
        url = store.shown_url
    check_enough(labelled.labels, labelled.valves)  # before a simulation of the prior
    prior_weight = DEFAULT_PRIOR_WEIGHT if args.prior_weight is None else args.prior_weight
    prior = None
    if prior_weight > 0:
        if args.dataset is not None:
            prior = Dataset.load(args.dataset)
        else:
            prior, cached = cached_dataset(args.variants, args.count, args.seed)
            if not cached:
                print(f"simulated the prior population ({len(prior)} tests; kept in the cache for next time)",
                      file=sys.stderr)
    current = ValveClassifier()  # the station's model: adopted, else shipped
    result = train_from_labels(labelled, prior, current, prior_weight=prior_weight, seed=args.seed, name=args.name,
                               source={"history": url})
    stop_if_interrupted()  # a candidate a library trained on after Ctrl-C is not written
    out = args.candidate_file or station_models_dir() / "candidates" / f"{result.name}.onnx"
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        atomic_write(out, lambda handle: handle.write(result.candidate.onnx_bytes))
    except OSError as exc:
        raise ConfigError(f"cannot write the candidate {out}: {exc.strerror}") from None
    figures = {"labels": result.labels, "worn_or_faulty": int(labelled.labels.sum()), "folds": result.folds,
               "prior_rows": result.prior_rows, "prior_weight_in_real_tests": result.prior_weight,
               "candidate": {"name": result.name, "file": str(out), **result.candidate_cv.as_dict()},
               "current": {"sha256": current.sha256, **result.current.as_dict()}}
    if args.json:
        print(json.dumps(figures, indent=2))
        return 0
    cand, now = result.candidate_cv, result.current
    print(f"{result.labels} labelled tests from {url} ({figures['worn_or_faulty']} worn or faulty); prior: "
          f"{result.prior_rows} simulated tests counting as {result.prior_weight:g} real ones")
    print(f"{result.folds}-fold cross-validation on the shop's labels (each test judged by a model that never saw it):")
    print(f"{'':32} {'accuracy':>9} {'MARGINAL':>9} {'outside band':>13} {'worn passed':>12} {'reusable failed':>16}")
    for label, s in ((f"candidate {result.name}", cand), (f"current {current.name}", now)):
        print(f"{label:32} {s.accuracy:9.1%} {s.marginal:9d} {s.accuracy_outside_band:13.1%} {s.worn_passed:12d} "
              f"{s.reusable_failed:16d}")
    if now.in_sample:
        print(f"note: the current model {current.name} learnt from shop labels, likely these: its row is in-sample "
              "(optimistic), the candidate's is cross-validated")
    print(f"candidate written to {out}")
    print(f"adopt it (this station then judges with it): edc-bench train --adopt {out}")
    return 0
