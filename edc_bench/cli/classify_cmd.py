"""``edc-bench classify``: judge features, or a recorded test, outside a test."""

from __future__ import annotations

import argparse
import dataclasses
import json
from pathlib import Path
from typing import TYPE_CHECKING, Any

from edc_bench.cli.common import given_path, positive_float, print_quietly_if_closed
from edc_bench.cli.exit_codes import ExitCode, exit_code_for
from edc_bench.timefmt import local_text

if TYPE_CHECKING:
    from edc_bench.records.schema import Record
    from edc_bench.section import FeaturePair
    from edc_bench.verdict.baseline import Baseline
    from edc_bench.verdict.classifier import ValveClassifier
    from edc_bench.verdict.sections import BaselineSummary, ClassificationSummary
    from edc_bench.verdict.verdicts import Verdict


@dataclasses.dataclass(frozen=True)
class ClassifyReport:
    """What ``classify`` says: the verdict, the classification behind it, and how it stands to the record judged.

    Attributes
    ----------
    verdict : Verdict
        This classification's verdict (a record's INVALID is kept: a model never judges a bad test).
    variant : str or None
        The variant whose baseline and model judged (None: a record's INVALID, not judged).
    features : FeaturePair or None
        af and a1 as judged (None: not judged).
    classification : ClassificationSummary or None
        The model's judgement, naming the model exactly (None: not judged).
    baseline : BaselineSummary or None
        The new-valve baseline the features were related to.
    reasons : list of str or None
        Why the verdict is INVALID, or a caution (a nominal baseline).
    record_dir : str or None
        The record folder of a recorded INVALID.
    recorded_verdict : Verdict or None
        A judged record's own verdict.
    not_as_recorded : str or None
        The line that says this classification is not as the record says (None: it is).
    disagreements : list of str or None
        Where the record's verdict does not follow from its own figures.
    not_as_first_indexed : str or None
        How the record differs from what the history first indexed of its test (None: it does not, or no history).
    compared : bool
        A record was judged: the four fields above are part of the output (:func:`_finish` sets them).
    """

    verdict: Verdict
    variant: str | None = None
    features: FeaturePair | None = None
    classification: ClassificationSummary | None = None
    baseline: BaselineSummary | None = None
    reasons: list[str] | None = None
    record_dir: str | None = None
    recorded_verdict: Verdict | None = None
    not_as_recorded: str | None = None
    disagreements: list[str] | None = None
    not_as_first_indexed: str | None = None
    compared: bool = False

    def as_json(self) -> dict[str, Any]:
        """The ``--json`` output: the classification's fields at the top level (its ``verdict`` among them), in
        the order the command has always printed them."""
        if self.classification is not None:
            out: dict[str, Any] = {"variant": self.variant, "features": self.features,
                                   **self.classification.model_dump(mode="python"), "baseline": self.baseline}
        else:
            out = {"verdict": self.verdict, **({"variant": self.variant} if self.variant is not None else {})}
        if self.reasons is not None:
            out["reasons"] = self.reasons
        if self.record_dir is not None:
            out["record_dir"] = self.record_dir
        if self.compared:
            out.update(recorded_verdict=self.recorded_verdict, not_as_recorded=self.not_as_recorded,
                       disagreements=self.disagreements, not_as_first_indexed=self.not_as_first_indexed)
        return out


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Register the command."""
    p = sub.add_parser(
        "classify", help="classify af/a1 values or a record folder",
        description="Judge a valve from its identified af and a1 (--variant with --af and --a1), or from a record "
                    "folder written by 'edc-bench test'. The record's own verdict is reused if the test was "
                    "INVALID: a model never judges a bad test. A record's verdict is compared with this one: "
                    "where they differ, or the record's verdict does not follow from its own figures, one line "
                    "says so (both verdicts, and why) and the exit code is 13.",
    )
    p.add_argument("record_dir", nargs="?", type=given_path, default=None, help="a record folder")
    p.add_argument("--variant", default=None, metavar="NAME|PART|PATH", help="pump variant (for --af/--a1)")
    p.add_argument("--af", type=positive_float("af in V as 'edc-bench test' prints it, e.g. 0.07"), default=None,
                   help="identified af in V")
    p.add_argument("--a1", type=positive_float("a1 in V s/mm as 'edc-bench test' prints it, e.g. 0.0038"),
                   default=None, help="identified a1 in V s/mm")
    p.add_argument("--model", type=given_path, default=None,
                   help="ONNX model (default: the variant's own if its [diagnosis] model names one, else the "
                   "station's: the adopted one, else the packaged network)")
    p.add_argument("--nominal-baseline", action="store_true",
                   help="judge a variant that has no measured baseline against its nominal figures (as "
                        "'edc-bench test --nominal-baseline'); without it such a variant is not judged")
    p.add_argument("--json", action="store_true", help="print JSON")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    """Classify and report."""
    from edc_bench.config import load_variant
    from edc_bench.errors import ConfigError
    from edc_bench.records.reader import load_record
    from edc_bench.section import FeaturePair
    from edc_bench.verdict.judgement import classification_summary, classify_features
    from edc_bench.verdict.verdicts import Verdict

    record = None
    if args.record_dir is not None:
        if args.af is not None or args.a1 is not None:
            raise ConfigError("give either a record folder or --af and --a1, not both")
        record = load_record(args.record_dir)
        if record.verdict == Verdict.INVALID:
            out = ClassifyReport(Verdict.INVALID, reasons=list(record.reasons), record_dir=str(args.record_dir))
            return _finish(out, args.json, record, record_dir=args.record_dir)
        recorded = record.variant
        variant = load_variant(args.variant or recorded or None)
        if args.variant and recorded and variant.name != recorded:
            raise ConfigError(f"the record was measured on variant {recorded}; --variant {args.variant} is "
                              f"{variant.name}, another pump's baseline: leave --variant out (or give {recorded}'s "
                              "file)")
        af, a1 = _recorded_features(record, args.record_dir)
    else:
        if args.af is None or args.a1 is None:
            raise ConfigError("give --af and --a1 (with --variant), or a record folder")
        variant = load_variant(args.variant)
        af, a1 = args.af, args.a1
    from edc_bench.verdict.baseline import load_baseline
    from edc_bench.verdict.judgement import nominal_baseline_warning, not_calibrated_reason

    baseline = load_baseline(variant)
    if args.record_dir is None:
        _check_plausible(af, a1, baseline)  # typed values; a record's were measured
    if not baseline.calibrated and not args.nominal_baseline:
        out = ClassifyReport(Verdict.INVALID, variant=variant.name, reasons=[not_calibrated_reason(variant)])
        return _finish(out, args.json, record, "this station has no measured baseline for the variant now",
                       args.record_dir)
    judged, baseline, classifier = classify_features(variant, af, a1, args.model)
    summary = classification_summary(judged, classifier)
    out = ClassifyReport(summary.verdict, variant=variant.name, features=FeaturePair(af=af, a1=a1),
                         classification=summary, baseline=baseline.summary(),
                         reasons=None if baseline.calibrated else [nominal_baseline_warning(variant)])
    return _finish(out, args.json, record, "" if record is None else _why_else(record, baseline, classifier),
                   args.record_dir)


def _finish(out: ClassifyReport, as_json: bool, record: Record | None, why: str = "",
            record_dir: Path | None = None) -> int:
    """Report ``out``, with the line that says it is not as ``record`` says where that is so; the exit code.

    A record's verdict is not as recorded when this classification gives another verdict on the valve, or when
    the record's verdict does not follow from its own figures (:func:`~edc_bench.records.consistency.disagreements`):
    then one line says so, naming both verdicts and ``why`` (what differs between the test's judgement and this
    one), and the exit code is 13 (:attr:`~edc_bench.cli.exit_codes.ExitCode.NOT_REPRODUCED`), so a script never
    takes a verdict that disagrees with its record for a plain one. A record that is not what the history first
    indexed for its test (``record_dir`` given, a history there to ask) is said the same way.
    """
    from edc_bench.records.consistency import disagreements

    line = None
    if record is not None:
        found = disagreements(record)
        history = None
        if record_dir is not None:  # and what the history holds of it, where a history is there to ask
            from edc_bench.history.standing import history_standing

            standing = history_standing(record, record_dir)
            if standing is not None and standing.differs:
                history = standing.differs
        line = not_as_recorded(record, out.verdict, found, why, history)
        out = dataclasses.replace(out, recorded_verdict=record.verdict, not_as_recorded=line, disagreements=found,
                                  not_as_first_indexed=history, compared=True)
    shown = out
    print_quietly_if_closed(lambda: _report(shown, as_json))
    return ExitCode.NOT_REPRODUCED if line else exit_code_for(out.verdict)


def not_as_recorded(record: Record, verdict: str, found: list[str], why: str = "",
                    history: str | None = None) -> str | None:
    """The line for a classification ``verdict`` of ``record`` that is not as the record says (None: it is).

    Parameters
    ----------
    record : Record
        The record classified.
    verdict : str
        The verdict classify gives (the record's own for an INVALID record).
    found : list of str
        Where the record's verdict does not follow from its own figures
        (:func:`~edc_bench.records.consistency.disagreements`).
    why : str, optional
        What differs between the test's judgement and this one (another model or baseline), said when the
        verdicts differ.
    history : str, optional
        How record.json differs from the record the history first indexed for its test
        (:attr:`~edc_bench.history.standing.Standing.differs`).
    """
    differ = record.verdict.judges_the_valve and verdict != record.verdict
    if not (found or differ or history):
        return None
    head = (f"NOT as recorded: the record says {record.verdict}, classify says {verdict}" if differ else
            f"NOT as recorded: the record says {record.verdict}")
    tail = f"; {history}" if history else ""
    if found:
        return (f"{head}; the record's verdict does not follow from its own figures ({'; '.join(found)}): record.json "
                f"was changed after its test, its digests written again{tail}")
    if history:
        return head + tail
    return f"{head} ({why})" if why else head


def _why_else(record: Record, baseline: Baseline, classifier: ValveClassifier) -> str:
    """What differs between the test's judgement of ``record`` and classify's against ``baseline`` with
    ``classifier``: the coil, the model, the baseline (empty: none of them)."""
    from edc_bench.engine.problems import Problem

    why = []
    if Problem.COIL_OUT_OF_SPEC in record.problem_flags or (record.coil is not None and record.coil.in_spec is False):
        why.append("its coil is out of spec, which fails the valve whatever its wear and which classify does not "
                   "judge")
    if Problem.NOT_CALIBRATED in record.problem_flags:
        why.append("the test had no measured baseline for its variant")
    kept = record.classification
    if kept is not None and kept.model_sha256 and kept.model_sha256 != classifier.sha256:
        why.append(f"the test was judged by {kept.model_file or kept.model_name or 'another model'} "
                   f"(SHA-256 {kept.model_sha256[:12]}), classify by {classifier.path.name} "
                   f"({classifier.sha256[:12]})")
    then = record.baseline
    if then is not None and then.af_v is not None and then.a1_v_s_per_mm is not None \
            and (then.af_v, then.a1_v_s_per_mm) != (baseline.af_v, baseline.a1_v_s_per_mm):
        when = local_text(then.written_at) if then.written_at else then.source or "another"
        why.append(f"the test was judged against the baseline of {when} (af0 {then.af_v:.4g} V, a1_0 "
                   f"{then.a1_v_s_per_mm:.4g} V s/mm), classify against "
                   f"{local_text(baseline.written_at) if baseline.written_at else baseline.source} "
                   f"(af0 {baseline.af_v:.4g} V, a1_0 {baseline.a1_v_s_per_mm:.4g} V s/mm)")
    return "; ".join(why)


#: A worn valve measures a few times its new-valve baseline; this many times is a typing or unit error.
MAX_RATIO = 100.0


def _recorded_features(record: Record, folder: Path) -> tuple[float, float]:
    """af and a1 of a record: positive finite numbers, or a ConfigError naming the record."""
    import math

    from edc_bench.errors import ConfigError

    af, a1 = record.features.af, record.features.a1
    if af is None or a1 is None:
        raise ConfigError(f"{folder}: the record holds no features af and a1 (not a finished test's record)")
    if not (math.isfinite(af) and math.isfinite(a1) and af > 0 and a1 > 0):
        raise ConfigError(f"{folder}: the record's features af={af}, a1={a1} cannot be judged (they must be "
                          "positive numbers); replay the test: edc-bench replay " + str(folder))
    return af, a1


def _check_plausible(af: float, a1: float, baseline: Baseline) -> None:
    """Refuse features more than :data:`MAX_RATIO` times the baseline: a wrong unit or a typing error."""
    from edc_bench.errors import ConfigError

    for flag, value, base, unit in (("--af", af, baseline.af_v, "V"), ("--a1", a1, baseline.a1_v_s_per_mm, "V s/mm")):
        if not base / MAX_RATIO <= value <= base * MAX_RATIO:
            raise ConfigError(f"{flag} {value:g}: {value / base:.3g} times the new-valve baseline ({base:g} {unit}); "
                              f"a worn valve measures a few times it: give {flag[2:]} in {unit} as 'edc-bench test' "
                              "prints it")


def _report(out: ClassifyReport, as_json: bool) -> None:
    from edc_bench.records.writer import json_safe

    if as_json:
        print(json.dumps(json_safe(out.as_json()), indent=2))
        return
    print(f"verdict: {out.verdict}")
    judged = out.classification
    if judged is not None:
        rel = judged.features_rel
        source = out.baseline.source if out.baseline is not None else None
        print(f"af x{rel.af:.3f}, a1 x{rel.a1:.3f} of the new-valve baseline ({source or 'no source given'})")
        distance = "beyond the scan" if judged.distance is None else f"{judged.distance:+.3f}"
        print(f"P(faulty) = {judged.probability_faulty:.3f}, distance to the boundary {distance} "
              f"(marginal band {judged.marginal_band:g}, {judged.model} model)")
    for reason in out.reasons or []:
        print(f"  - {reason}")
    if out.not_as_recorded:
        print(out.not_as_recorded)
