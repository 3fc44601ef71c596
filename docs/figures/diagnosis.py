"""Figures of docs/diagnosis.md: the classifier, its training, the shop's labels, the paper's experiment.

Live figures (the shipped baselines, the ground truth's limit, the paper's vectors, the reproducibility rule) are
computed while the page is written. The population runs (``edc-bench evaluate``, ``train``, ``paper``,
``study-boundary``, ``train --from-history`` on a simulated shop, the coil study) are measurements, each run by
the function behind its command (the batch path), with the shipped models, in temporary data and cache folders
so that neither a station's adopted model nor its cache changes a figure.
"""

from __future__ import annotations

import contextlib
import dataclasses
import io
import os
import re
import shlex
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from figures.common import (
    isolated_station,
    measurement,
    percent,
    run_cli,
    shipped_classifier,
    stored,
    table,
)

if TYPE_CHECKING:
    from edc_bench.learning.evaluation import Evaluation

SHIPPED_VARIANTS = ("p-edc-default", "p-edc-long")
#: The paper's valves V1, V2, V3 (Tsai & Tseng 2010, section 4): identified af in V and a1 in V s/mm.
PAPER_VECTORS = {"V1": (0.0469, 0.0118), "V2": (0.0715, 0.0239), "V3": (0.1284, 0.0471)}
#: Boundary shifts the page tabulates (baseline-ratio units).
BOUNDARY_SHIFTS = (-0.10, -0.05, 0.0, 0.05, 0.10)


# --------------------------------------------------------------------------- helpers


def shipped_metadata(kind: str = "mlp") -> dict[str, str]:
    """The metadata the packaged model carries."""
    return dict(shipped_classifier(kind).metadata)


# --------------------------------------------------------------------------- coils (live text, measured figures)


@measurement("diagnosis-coil", minutes=0.5)
def coil_population() -> dict[str, Any]:
    """300 p-edc-default valves with coils over the spec at 20-80 degC against the same valves' nominal coil.

    The batch path, the same noise both ways (the slow test ``test_population_verdicts_do_not_depend_on_the_coil``).
    """
    from edc_bench.config import load_variant
    from edc_bench.experiments.studies import coil_population_study

    study = coil_population_study(load_variant("p-edc-default"), shipped_classifier(), 300, seed=17)
    ok, outside, same = study.converged, study.outside_band, study.same_verdict
    d_af, d_a1, ohms = study.af_change_rel, study.a1_change_rel, study.coil_ohm
    return {"valves": len(ohms), "converged": int(ok.sum()), "outside_band": int(outside.sum()),
            "kept_outside": int(same[outside].sum()), "kept": int(same.sum()),
            "ohm_min": round(float(ohms.min()), 3), "ohm_max": round(float(ohms.max()), 3),
            "af_mean": round(float(d_af.mean()), 5), "af_max": round(float(np.abs(d_af).max()), 5),
            "a1_mean": round(float(d_a1.mean()), 5), "a1_max": round(float(np.abs(d_a1).max()), 5),
            "coil_max": round(float(np.abs(study.coil_error_rel).max()), 5)}


def coil_paragraph() -> str:
    """The coil study's paragraph, from ``diagnosis-coil`` and ``diagnosis-training``."""
    c = stored("diagnosis-coil")
    both = "all" if c["converged"] == c["valves"] else f"{c['converged']} of {c['valves']}"
    kept = c["kept_outside"] / max(c["outside_band"], 1)
    return (f"Over {c['valves']} simulated `p-edc-default` valves with coils over "
            f"{c['ohm_min']:.2f}-{c['ohm_max']:.2f} ohm starting at 20-80 degC, against the same valves with the "
            f"nominal coil at 20 degC (batch path, the same sensor noise; the slow test "
            f"`test_population_verdicts_do_not_depend_on_the_coil`): {both} converged both ways; of the "
            f"{c['outside_band']} outside the marginal band, {percent(kept, 0 if kept == 1 else 1)} kept their "
            f"verdict ({c['kept']} of {c['converged']} in all); af moved {percent(c['af_mean'], 2, sign=True)} on "
            f"average and {percent(c['af_max'], 2)} at most, a1 {percent(c['a1_mean'], 2, sign=True)} and "
            f"{percent(c['a1_max'], 2)} at most; the measured coil resistance was within {percent(c['coil_max'], 2)} "
            f"of the simulated coil's. The shipped baselines were calibrated and both models trained on these "
            f"features (training accuracy {training_accuracies()}, `edc-bench train`).")


# --------------------------------------------------------------------------- baselines and ground truth (live)


def shipped_baselines_paragraph() -> str:
    """Where the shipped baselines come from and their uncertainty, read from ``configs/baselines/``."""
    from edc_bench.config import load_variant
    from edc_bench.verdict.baseline import load_baseline

    rows = []
    for name in SHIPPED_VARIANTS:
        b = load_baseline(load_variant(name), station=False)
        words = shlex.split(b.command)
        seed = words[words.index("--seed") + 1] if "--seed" in words else "?"
        rows.append((name, b.tests, seed, b.af_uncertainty_v / b.af_v, b.a1_uncertainty_v_s_per_mm / b.a1_v_s_per_mm))
    counts = {(n, s) for _, n, s, _, _ in rows}
    how = (f"on {rows[0][1]} simulated new valves each (seed {rows[0][2]})" if len(counts) == 1 else
           ", ".join(f"`{r[0]}` on {r[1]} simulated new valves (seed {r[2]})" for r in rows))
    spread = "; ".join(f"`{r[0]}` {percent(r[3])} in af and {percent(r[4])} in a1" for r in rows)
    paper = load_baseline(load_variant("paper"), station=False)
    return (f"The shipped `{SHIPPED_VARIANTS[0]}` and `{SHIPPED_VARIANTS[1]}` baselines were calibrated {how}. "
            f"Their standard uncertainty (the spread over the square root of the number of valves): {spread}. "
            f"The `paper` variant's baseline is the paper's new valve V1 (Tsai & Tseng 2010, section 4: "
            f"af = {paper.af_v:g}, a1 = {paper.a1_v_s_per_mm:g}). Training and evaluation compare simulated "
            f"features with the library's baseline, never a station's.")


def ground_truth_sentence() -> str:
    """Where ``p-edc-default``'s limit lies, in clearance, from its ``[diagnosis]`` and ``[valve]`` tables."""
    from edc_bench.config import load_variant
    from edc_bench.physics.valve import ValveSpec
    from edc_bench.physics.wear import (
        clearance_for_resisting_force,
        is_faulty,
        resisting_force_n,
    )

    v = load_variant("p-edc-default")
    d = v.diagnosis
    new = v.valve.presets["new"]
    new_force = resisting_force_n(v, ValveSpec(new.clearance_mm, new.roughness))
    fails_at = clearance_for_resisting_force(v, d.resistance_limit_n)
    worn, faulty = v.valve.presets["worn"].clearance_mm, v.valve.presets["faulty"].clearance_mm
    fails = {name: is_faulty(v, ValveSpec(p.clearance_mm, p.roughness)) for name, p in v.valve.presets.items()}
    failing = " and ".join(f"`{name}`" for name, bad in fails.items() if bad) or "no"
    passing = " and ".join(f"`{name}`" for name, bad in fails.items() if not bad) or "none"
    return (f"For `p-edc-default` ({d.resistance_speed_mm_s:g} mm/s, {d.resistance_limit_n:g} N: "
            f"{d.resistance_limit_n / new_force:.2f} times a new valve's) an evenly worn valve fails at "
            f"{fails_at:.3f} mm clearance (spec {v.valve.clearance_spec_mm:g} mm; the presets: `new` "
            f"{new.clearance_mm:g} mm, `faulty` {faulty:g} mm and unevenly worn, `worn` {worn:g} mm); the "
            f"{failing} presets fail, {passing} passes. Labels never come from identified values.")


def paper_vectors_sentence() -> str:
    """``edc-bench classify --variant paper`` on the paper's three valves, judged now by the packaged network."""
    from edc_bench.config import load_variant
    from edc_bench.verdict.classifier import packaged_model_path
    from edc_bench.verdict.judgement import classify_features

    variant = load_variant("paper")
    af0, a10 = PAPER_VECTORS["V1"]
    parts = []
    for name, (af, a1) in PAPER_VECTORS.items():
        judged, _, _ = classify_features(variant, af, a1, packaged_model_path())
        ratios = "" if name == "V1" else f" (af x{af / af0:.2f}, a1 x{a1 / a10:.2f} of V1)"
        parts.append(f"{name}{ratios} {judged.verdict}")
    return (f"`edc-bench classify --variant paper` judges the paper's own vectors (its section 4): "
            f"{'; '.join(parts)}.")


# --------------------------------------------------------------------------- training (measured) and reproducibility


@measurement("diagnosis-training", minutes=0.8)
def training() -> dict[str, Any]:
    """``edc-bench train`` with its defaults, into a temporary models folder: accuracies, rows, the data's hash."""
    with isolated_station() as root:
        code, out, _ = run_cli(["train", "--models-dir", str(root)])
    if code != 0:
        raise RuntimeError(f"edc-bench train exited {code}")
    accuracy = {m.group(1): float(m.group(2)) for m in re.finditer(r"^(\w+): training accuracy ([\d.]+)", out, re.MULTILINE)}
    rows = int(re.search(r"on (\d+) tests", out).group(1))
    return {"mlp_accuracy": round(accuracy["mlp"], 4), "linear_accuracy": round(accuracy["linear"], 4),
            "rows": rows, "sha256": re.search(r"training data sha256 (\w+)", out).group(1)}


def training_accuracies() -> str:
    """'0.997 for both', or each model's, from ``diagnosis-training``."""
    t = stored("diagnosis-training")
    mlp, linear = f"{t['mlp_accuracy']:.3f}", f"{t['linear_accuracy']:.3f}"
    return f"{mlp} for both models" if mlp == linear else f"{mlp} for the network, {linear} for the linear model"


def training_sentence() -> str:
    """What ``edc-bench train`` gives today, beside what the shipped models record."""
    from edc_bench.cli.train_cmd import DEFAULT_COUNT, DEFAULT_SEED, DEFAULT_VARIANTS

    t = stored("diagnosis-training")
    meta = shipped_metadata()
    same = ("the hash the shipped models record" if meta["edc_bench.training_data_sha256"] == t["sha256"] else
            f"not the hash the shipped models record ({meta['edc_bench.training_data_sha256'][:16]}...): "
            "they need rebuilding")
    return (f"{DEFAULT_COUNT:,} valves per training variant ({', '.join(f'`{v}`' for v in DEFAULT_VARIANTS)}; "
            f"seed {DEFAULT_SEED}) through the batch path; only tests the trust rule trusts are used: "
            f"{t['rows']:,} tests, training accuracy {training_accuracies()}, training data sha256 "
            f"{t['sha256'][:16]}..., {same}.")


def reproducibility_paragraph() -> str:
    """What the models' metadata sees of another machine's arithmetic: the digits the code hashes and stores."""
    from edc_bench.learning.dataset import HASH_SIGNIFICANT_DIGITS
    from edc_bench.learning.train import STORED_SIGNIFICANT_DIGITS

    words = {6: "six", 7: "seven", 8: "eight", 9: "nine", 10: "ten"}
    hashed = words.get(HASH_SIGNIFICANT_DIGITS, str(HASH_SIGNIFICANT_DIGITS))
    kept = words.get(STORED_SIGNIFICANT_DIGITS, str(STORED_SIGNIFICANT_DIGITS))
    return (f"What is the same on every machine, and what is not. Another CPU or BLAS computes the same "
            f"simulation to within its last bits. The metadata does not see that: the training data's hash is "
            f"taken over the values to {hashed} significant digits, and the scaler's figures are stored to {kept} "
            f"(`tests/learning/test_train.py` perturbs the data by 1e-12 relative and gets the same metadata). The "
            f"graph's float32 weights are another matter: training can carry a difference in the last bits of its "
            f"input into the last bit of a weight, so a machine whose arithmetic differs may build a file that "
            f"differs in those bits, and the byte-for-byte test then says so.")


# --------------------------------------------------------------------------- the shop's labels (measured)


SHOP_COUNT = 300


@measurement("diagnosis-shop", minutes=1.0)
def shop() -> dict[str, Any]:
    """The simulated shop and ``edc-bench train --from-history`` on it, in a temporary station."""
    from edc_bench.history import simulated_shop

    with isolated_station() as root:
        out = io.StringIO()
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(io.StringIO()):
            if simulated_shop.main(["--db", "sqlite:///shop.sqlite", "--count", str(SHOP_COUNT)]) != 0:
                raise RuntimeError("simulated_shop failed")
        code, trained, _ = run_cli(["train", "--from-history", "--db", "sqlite:///shop.sqlite"])
        if code != 0:
            raise RuntimeError(f"edc-bench train --from-history exited {code}")
        data = str(Path(os.environ["EDC_BENCH_DATA_DIR"]))
    transcript = (out.getvalue() + trained).replace(data, "...").replace(str(root), ".")
    rows = {}
    for line in transcript.splitlines():
        words = line.split()
        if words and words[0] in ("candidate", "current") and len(words) == 7:
            rows[words[0]] = {"accuracy": words[2], "marginal": int(words[3]), "outside_band": words[4],
                              "worn_passed": int(words[5]), "reusable_failed": int(words[6])}
    return {"transcript": transcript.rstrip("\n"), "rows": rows}


def shop_transcript() -> str:
    """The two commands' output, as a code block."""
    return "```\n" + stored("diagnosis-shop")["transcript"] + "\n```"


def shop_paragraph() -> str:
    """What the shop's comparison shows."""
    rows = stored("diagnosis-shop")["rows"]
    cand, now = rows["candidate"], rows["current"]
    margin = float(cand["accuracy"].rstrip("%")) - float(now["accuracy"].rstrip("%"))
    failed = ("fails no reusable one" if cand["reusable_failed"] == 0 else
              f"fails {cand['reusable_failed']} reusable ones (the shipped model {now['reusable_failed']})")
    return (f"The candidate passes {cand['worn_passed']} worn valves where the shipped model passes "
            f"{now['worn_passed']}, and {failed}: cross-validated accuracy {cand['accuracy'].replace('%', ' %')} "
            f"against {now['accuracy'].replace('%', ' %')}, a margin of {margin:.1f} points on the shop's own labels.")


# --------------------------------------------------------------------------- held-out population (measured)


@measurement("diagnosis-evaluate", minutes=0.5)
def held_out() -> dict[str, Any]:
    """``edc-bench evaluate`` with its defaults (the held-out seed), judged by the packaged network and linear model."""
    from edc_bench.learning.dataset import make_dataset
    from edc_bench.learning.evaluation import evaluate

    count, seed = 300, 777
    dataset = make_dataset(SHIPPED_VARIANTS, count, seed)
    out: dict[str, Any] = {"count_per_variant": count, "seed": seed}
    for kind in ("mlp", "linear"):
        out[kind] = _evaluation_figures(evaluate(shipped_classifier(kind), dataset))
    return out


#: What the pages keep of an ``evaluate`` report.
_EVALUATION_KEYS = ("tests", "invalid", "judged", "marginal", "faulty_passed", "reusable_failed", "faulty", "reusable")


def _evaluation_figures(report: Evaluation, *more: str) -> dict[str, Any]:
    """An ``evaluate`` report's figures as a page stores them (``more``: further keys)."""
    figures = dataclasses.asdict(report)
    return {**{k: figures[k] for k in _EVALUATION_KEYS + more},
            "accuracy_outside_band": round(report.accuracy_outside_band, 6)}


def held_out_table() -> str:
    """The held-out population's figures, one row per model."""
    e = stored("diagnosis-evaluate")
    rows = []
    for kind, label in (("mlp", "the packaged network (`edc-bench evaluate`)"),
                        ("linear", "the linear model (`--model edc_bench/verdict/models/valve_linear.onnx`)")):
        r = e[kind]
        rows.append((label, r["tests"], r["invalid"], f"{r['marginal']} ({percent(r['marginal'] / r['judged'])})",
                     percent(r["accuracy_outside_band"], 2), r["faulty_passed"], r["reusable_failed"]))
    head = (f"Held-out population: {e['mlp']['tests']} valves ({e['count_per_variant']} of each training variant, "
            f"seed {e['seed']}, not used in training), `edc-bench evaluate` with its defaults; "
            f"{e['mlp']['faulty']} faulty and {e['mlp']['reusable']} reusable by physics:\n\n")
    body = table(("model", "valves", "INVALID", "MARGINAL", "right outside the band", "faulty passed",
                  "reusable failed"), rows)
    return head + body + "\n\n" + held_out_paragraph()


@measurement("diagnosis-own-model", minutes=0.5)
def own_model() -> dict[str, Any]:
    """``edc-bench evaluate --variants p-edc-hard`` (the held-out seed, 300 valves), judged by the variant's own
    network (the default) and by the shipped one (``--model``)."""
    from edc_bench.learning.dataset import make_dataset
    from edc_bench.learning.evaluation import evaluate

    count, seed = 300, 777
    with isolated_station():
        dataset = make_dataset(["p-edc-hard"], count, seed)
        out: dict[str, Any] = {"count": count, "seed": seed}
        for label, classifier in (("own", None), ("shipped", shipped_classifier())):
            out[label] = _evaluation_figures(evaluate(classifier, dataset), "models")
    return out


def own_model_table() -> str:
    """The hard pump's held-out valves judged by its own network and by the shipped one."""
    e = stored("diagnosis-own-model")
    rows = []
    for key, label in (("own", f"its own, `{e['own']['models'][0]}` (`edc-bench evaluate --variants p-edc-hard`)"),
                       ("shipped", "the shipped network (`--model edc_bench/verdict/models/valve_mlp.onnx`)")):
        r = e[key]
        rows.append((label, r["tests"], f"{r['marginal']} ({percent(r['marginal'] / r['judged'])})",
                     percent(r["accuracy_outside_band"], 2), r["faulty_passed"], r["reusable_failed"]))
    head = (f"{e['own']['tests']} held-out valves of `p-edc-hard` (seed {e['seed']}, not used in training; "
            f"{e['own']['faulty']} faulty and {e['own']['reusable']} reusable by physics):\n\n")
    return head + table(("judged by", "valves", "MARGINAL", "right outside the band", "faulty passed",
                         "reusable failed"), rows)


def held_out_paragraph() -> str:
    """What the held-out figures say about the boundary and the band."""
    e = stored("diagnosis-evaluate")
    same = all(e["mlp"][k] == e["linear"][k] for k in ("marginal", "faulty_passed", "reusable_failed"))
    errors = sum(e[k]["faulty_passed"] + e[k]["reusable_failed"] for k in ("mlp", "linear"))
    band = shipped_classifier().marginal_band
    text = ("The linear model gives the same figures: with these labels the boundary is a straight line in "
            "(af, a1), as the paper observed. " if same else
            "The linear model's figures differ from the network's: with these labels the boundary is not quite a "
            "straight line in (af, a1). ")
    if errors == 0:
        text += (f"On this population no valve outside the {band * 100:g} % band was judged wrong; other "
                 "populations and plants (the time-to-verdict study in bench-test.md, the boundary study below, "
                 "the gain sweep in method.md) do have a few errors outside it, near the boundary. On real valves "
                 "the band would have to be set from measured repeatability.")
    else:
        text += ("Errors outside the band occur even in simulation; on real valves the band would have to be set "
                 "from measured repeatability.")
    return text


# --------------------------------------------------------------------------- the paper's experiment (measured)


PAPER_SEED = 2010
PAPER_RUNS = 10


def paper_run(job: tuple[str, int]) -> dict[str, int]:
    """One run of the paper's protocol (``edc-bench paper --variant NAME --seed SEED``): the valves judged right."""
    from edc_bench.experiments.studies import paper_experiment

    return dataclasses.asdict(paper_experiment(*job).outcome)


@measurement("diagnosis-paper", minutes=1.5)
def paper() -> dict[str, Any]:
    """``edc-bench paper`` (seed 2010) and ``--runs 10 --seed 0`` for both shipped variants, over all cores."""
    from concurrent.futures import ProcessPoolExecutor

    jobs = [(SHIPPED_VARIANTS[0], PAPER_SEED)] + [(name, seed) for name in SHIPPED_VARIANTS
                                                  for seed in range(PAPER_RUNS)]
    with ProcessPoolExecutor(max_workers=os.cpu_count() or 1) as pool:
        results = list(pool.map(paper_run, jobs))
    runs = {name: [r["reusable_right"] + r["faulty_right"] for (n, _), r in zip(jobs[1:], results[1:], strict=True)
                   if n == name] for name in SHIPPED_VARIANTS}
    return {"seed": PAPER_SEED, "simulation": results[0], "runs": runs}


def paper_table() -> str:
    """The paper's outcome beside the simulation's."""
    from edc_bench.experiments.studies import PAPER_OUTCOME, PaperOutcome

    p, s = PAPER_OUTCOME, PaperOutcome(**stored("diagnosis-paper")["simulation"])
    rows = [("reusable judged normal", f"{p.reusable_right} / {p.reusable}", f"{s.reusable_right} / {s.reusable}"),
            ("faulty judged abnormal", f"{p.faulty_right} / {p.faulty}", f"{s.faulty_right} / {s.faulty}"),
            ("valves right", f"{p.right} / {p.valves}", f"{s.right} / {s.valves}")]
    return table(("", "paper (2010)", f"simulation, seed {stored('diagnosis-paper')['seed']}"), rows)


def paper_runs_sentence() -> str:
    """How many seeds do at least as well as the paper."""
    from edc_bench.experiments.studies import PAPER_OUTCOME

    paper_right = PAPER_OUTCOME.right
    runs = stored("diagnosis-paper")["runs"]
    parts = [f"`{name}` {sum(t >= paper_right for t in totals)} of {len(totals)} (worst {min(totals)}/18)"
             for name, totals in runs.items()]
    return (f"Over seeds 0-{PAPER_RUNS - 1} (`edc-bench paper --runs {PAPER_RUNS} --seed 0`, and with "
            f"`--variant {SHIPPED_VARIANTS[1]}`), the runs that get at "
            f"least {paper_right}/18 right, as the paper did: {' and '.join(parts)}.")


# --------------------------------------------------------------------------- the boundary study (measured)


@measurement("diagnosis-boundary", minutes=1.0)
def boundary() -> dict[str, Any]:
    """``edc-bench study-boundary`` with its defaults (1000 valves per shipped variant, seed 31)."""
    from edc_bench.experiments.studies import boundary_tradeoff
    from edc_bench.learning.dataset import make_dataset

    count, seed = 1000, 31
    dataset = make_dataset(SHIPPED_VARIANTS, count, seed)
    curve = boundary_tradeoff(shipped_classifier(), dataset, np.array(BOUNDARY_SHIFTS))
    return {"valves": len(dataset), "seed": seed,
            "rows": [[s, round(float(n), 5), round(float(f), 5)] for s, n, f in
                     zip(BOUNDARY_SHIFTS, curve.needless_replacement, curve.faulty_passed, strict=True)]}


def boundary_table() -> str:
    """Needless replacements and faulty valves passed, per boundary shift."""
    b = stored("diagnosis-boundary")
    head = (f"{b['valves']:,} simulated valves (both training variants, seed {b['seed']}); the trained boundary moved "
            f"by a shift in baseline-ratio units (positive: fewer valves fail):\n\n")
    rows = [(f"{s:+.2f}" if s else "0.00 (trained)", percent(n), percent(f)) for s, n, f in b["rows"]]
    return head + table(("shift", "reusable valves replaced needlessly", "faulty valves passed"), rows)


# --------------------------------------------------------------------------- which part is at fault (measured)

#: The variants the part study runs on: the default pump, the hard one (a solenoid whose pull varies +/-10 % over the
#: swing, Stribeck friction) and the long-stroke one.
PART_STUDY_VARIANTS = ("p-edc-default", "p-edc-hard", "p-edc-long")
PART_STUDY_TESTS = 6
PART_STUDY_SEED = 4100


@measurement("diagnosis-parts", minutes=5.0)
def parts_study() -> dict[str, Any]:
    """``edc-bench evaluate --parts`` on each of :data:`PART_STUDY_VARIANTS`: every case's counts and the headline."""
    from edc_bench.config import load_variant
    from edc_bench.studies.part_study import run_part_study, study_json

    return {name: study_json(run_part_study(load_variant(name), PART_STUDY_TESTS, PART_STUDY_SEED))
            for name in PART_STUDY_VARIANTS}


#: The binds and steps the uneven reading's share is measured on (``diagnosis-uneven-shares``): binds near either end
#: of the swing (where they leak the most into the bend), steps of the sensor nearer mid-swing (nearer the ends a
#: step is read as the solenoid's pull: docs/diagnosis.md); each on three valves.
UNEVEN_BINDS_N = (0.5, 1.0)
UNEVEN_STEP_MM = 0.3
UNEVEN_SEEDS = (1, 2, 3)


@measurement("diagnosis-uneven-shares", minutes=1.0)
def uneven_shares() -> dict[str, Any]:
    """The bend alike in both directions over the friction's rise (the share :data:`~edc_bench.verdict.part.
    UNEVEN_SHARE` holds to) of binds and of the sensor's steps, where a rack finding is beyond its limit: the most a
    bind gave and the least a step gave, per variant."""
    from edc_bench.bench import run_simulated_test
    from edc_bench.config import load_variant
    from edc_bench.verdict.part import UNEVEN_SHARE
    from edc_bench.verdict.part_sections import Signature

    out: dict[str, Any] = {"threshold": UNEVEN_SHARE}
    for name in PART_STUDY_VARIANTS:
        variant = load_variant(name)
        mid, swing = variant.rack.mid_stroke_mm, sum(t.amplitude_mm for t in variant.excitation.active_tones)

        def shares(rack: str, sensor: str) -> list[float]:
            found = []
            for seed in UNEVEN_SEEDS:
                part = run_simulated_test(variant, "new", seed, rack_fault=rack, sensor_fault=sensor).judgement.part
                uneven = part.finding(Signature.SENSOR_UNEVEN) if part is not None else None
                if uneven is not None and uneven.limit > 0:
                    found.append(UNEVEN_SHARE * abs(uneven.figure) / uneven.limit)
            return found

        binds = [x for n in UNEVEN_BINDS_N for at in (mid - 0.7 * swing, mid + 0.7 * swing)
                 for x in shares(f"bind_n={n},bind_width_mm=1,bind_at_mm={at:.2f}", "none")]
        steps = [x for at in (mid - 0.45 * swing, mid + 0.45 * swing)
                 for x in shares("none", f"step_mm={UNEVEN_STEP_MM},step_width_mm=1,step_at_mm={at:.2f}")]
        out[name] = {"binds": len(binds), "bind_max": round(max(binds), 3) if binds else None,
                     "steps": len(steps), "step_min": round(min(steps), 3) if steps else None}
    return out


def uneven_share_range() -> str:
    """The measured shares, for the signatures' table: binds' most, steps' least, over the variants."""
    m = stored("diagnosis-uneven-shares")
    rows = [m[v] for v in PART_STUDY_VARIANTS]
    binds = [r["bind_max"] for r in rows if r["bind_max"] is not None]
    steps = [r["step_min"] for r in rows if r["step_min"] is not None]
    return (f"binds of {' and '.join(f'{n:g}' for n in UNEVEN_BINDS_N)} N near either end of the swing on the three "
            f"shipped pumps leak at most {max(binds):.2f} of their rise into this bend ({sum(r['binds'] for r in rows)} "
            f"tests), where {UNEVEN_STEP_MM:g} mm steps of the sensor that the rack's findings took for a bind or "
            f"slope bend it at least {min(steps):.2f} of the rise ({sum(r['steps'] for r in rows)} tests; "
            f"`python docs/regenerate.py --measure diagnosis-uneven-shares`)")


def parts_table(variant: str) -> str:
    """The part study's confusion matrix for one variant (``diagnosis-parts``)."""
    from edc_bench.studies.part_study import PART_COLUMNS, VERDICT_COLUMNS

    study = stored("diagnosis-parts")[variant]
    header = ["case", "beyond its limit", "tests", *(f"named: {p}" for p in PART_COLUMNS), *VERDICT_COLUMNS,
              "told: replace the valve", "named right"]
    rows = [[c["case"], "yes" if c["beyond_limit"] else "no", c["tests"],
             *(c["parts"].get(p, 0) for p in PART_COLUMNS), *(c["verdicts"].get(v, 0) for v in VERDICT_COLUMNS),
             c["told_replace"], f"{c['named_right']}/{c['tests']}"] for c in study["cases"]]
    return table(header, rows)


def parts_summary(variant: str) -> str:
    """The part study's headline for one variant, as a list."""
    from edc_bench.studies.part_study import PartSummary, summary_lines

    summary = PartSummary(**stored("diagnosis-parts")[variant]["summary"])
    return "\n".join(f"- {line}" for line in summary_lines(summary))
