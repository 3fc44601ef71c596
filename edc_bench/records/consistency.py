"""Does a record's verdict follow from its own figures? The check beyond the integrity manifest.

The manifest (:mod:`~edc_bench.records.integrity`) catches a record edited by hand, but its digests carry no
secret: someone who edits the verdict and writes the digests again gets past it. The record still holds every
figure its verdict was decided from, and the rules that decided it are the bench's own code, so
:func:`disagreements` decides the verdict again from those figures with that code and names each place where
the record disagrees with itself:

1. the verdict, from the problems and the classifier's verdict the record keeps
   (:func:`~edc_bench.verdict.judgement.verdict_of`, the rule the test decided by);
2. the trust rule's problems, from the identification, timing and loop figures under the acceptance limits of
   the variant as the test ran it (:func:`~edc_bench.identification.trust.trust_problems`; records of schema 4
   on, which keep the problems as values);
3. the coil's ``in_spec``, from its resistance at 20 degC and its spec
   (:func:`~edc_bench.identification.coil_check.in_spec`), and the problem it makes; and the problem "pump
   fault" where, and only where, the part diagnosis did not judge the valve (records of schema 11 on);
4. the classifier's verdict, from its P(faulty), distance, threshold and marginal band
   (:func:`~edc_bench.verdict.classifier.verdicts_of`);
5. the relative features, from the features and the baseline; the features, from the identified parameters;
6. P(faulty) and the classifier's verdict from the model itself at the relative features, when the model the
   record names by its SHA-256 is on this station (:func:`~edc_bench.verdict.classifier.find_model`); else the
   valve's side of the boundary from the decision plane the record keeps, where the plane leaves no doubt;
7. a retest's decision, from its verdict and the variant's ``[retest]`` rule (:func:`~edc_bench.verdict.retest.decide`).

What a record cannot say is not claimed: a record without a classification (INVALID, UNCLASSIFIED) is held to
its problems alone, a figure an older record lacks is passed over, and an INVALID record older than schema 4
(its problems kept only as sentences) is taken as it says. A record forged to agree with itself everywhere,
from its verdict back to its identified parameters, passes: replaying its CAN log (``edc-bench replay``) or the
history's digest of the record as first indexed is what catches that.
"""

from __future__ import annotations

import math
import shlex
from collections.abc import Callable
from pathlib import Path

from edc_bench.engine.problems import Problem
from edc_bench.records.schema import ClassificationSummary, Record
from edc_bench.verdict.verdicts import Verdict

#: The record schema from which record.json keeps the verdict's problems as values (before: sentences only).
PROBLEMS_SCHEMA = 4
#: The first record schema whose host stalls cost the rows they touched, not the test (the trust rule's timing)
STALL_ROWS_SCHEMA = 9
#: The first record schema that names the part at fault (``part``: the valve, the rack or the rack-travel sensor)
PART_SCHEMA = 11
#: Two figures the test computed from one another agree to this (relative): a JSON round trip keeps them exactly.
SAME_REL = 1e-9
#: P(faulty) from the model named by the record agrees with the record's to this (onnxruntime on another CPU).
SAME_PROBABILITY = 1e-3


def disagreements(record: Record) -> list[str]:
    """Where ``record``'s verdict does not follow from its own figures, one line each.

    Parameters
    ----------
    record : Record
        A record as :func:`~edc_bench.records.reader.load_record` reads it.

    Returns
    -------
    list of str
        Each disagreement in words, e.g. ``the verdict is PASS but its classification says FAIL``; empty when the
        verdict follows from the figures, or the record holds too little to say. A check that needs more than the
        record (the history's digest of it as first indexed) is added beside these.
    """
    found: list[str] = []
    for check in _CHECKS:
        found += check(record)
    return found


def refusal(folder: Path, record: Record, found: list[str], refused: str = "not read") -> str:
    """The one line a reader refuses ``record`` (in ``folder``) with, for the :func:`disagreements` ``found``;
    ``refused`` says what the reader did not do (``not read``, ``no report drawn``)."""
    return (f"{folder}: its verdict {record.verdict} does not follow from its own figures ({'; '.join(found)}): "
            f"{refused}. record.json was changed after its test, its digests written again; 'edc-bench replay "
            f"{shlex.quote(str(folder))}' shows what the test's own CAN log gives")


def _problems(record: Record) -> Problem | None:
    """The problems ``record`` lists (None: a name this edc-bench does not know)."""
    try:
        return Problem.from_names(record.problems)
    except KeyError:
        return None


def _names(problems: Problem) -> str:
    return ", ".join(problems.names) or "none"


def _verdict(record: Record) -> list[str]:
    """1: the verdict from the problems and the classifier's verdict, by the rule the test decided by."""
    from edc_bench.verdict.judgement import verdict_of

    problems = _problems(record)
    if problems is None:
        return []
    if record.coil is not None and record.coil.in_spec is False:
        problems |= Problem.COIL_OUT_OF_SPEC  # an older record's problems may not name it (3 checks them)
    classified = record.classification.verdict if record.classification is not None else None
    expected = verdict_of(problems, classified)
    if expected == record.verdict:
        return []
    if record.verdict == Verdict.INVALID and record.schema_version < PROBLEMS_SCHEMA:
        return []  # its trust problems are in its reasons' words only: the record cannot say
    from edc_bench.identification.trust import TRUST_PROBLEMS

    if problems & TRUST_PROBLEMS:
        why = f"its problems ({_names(problems & TRUST_PROBLEMS)}) make it INVALID"
    elif Problem.COIL_OUT_OF_SPEC in problems:
        why = "its coil out of spec makes it FAIL"
    elif Problem.PUMP_FAULT in problems:
        why = "its rack or rack-travel sensor at fault makes it INVALID"
    elif Problem.NOT_CALIBRATED in problems:
        why = "its variant not calibrated makes it INVALID"
    elif classified is not None:
        why = f"its classification says {classified}"
    else:
        why = "it holds no classification and no problem (a trustworthy test not classified is UNCLASSIFIED)"
    return [f"the verdict is {record.verdict} but {why}"]


def _trust(record: Record) -> list[str]:
    """2: the trust rule's problems from the figures they were decided from, under the variant's limits as run."""
    from edc_bench.config.models import AcceptanceSection
    from edc_bench.identification.trust import TRUST_PROBLEMS, trust_problems

    problems = _problems(record)
    if problems is None or record.schema_version < PROBLEMS_SCHEMA or not isinstance(record.config, dict):
        return []
    try:
        acceptance = AcceptanceSection.model_validate(record.config.get("acceptance") or {})
    except ValueError:
        return []  # a variant this edc-bench no longer reads: the record cannot say
    ident, loop = record.identification, record.loop
    aborted = loop.abort is not None
    if ident is None:
        derived = Problem.NOT_IDENTIFIED | (Problem.ABORTED if aborted else Problem.NONE)
    else:
        if ident.settled is None:
            return []
        fit = ident.model_fit
        # None: a NaN or an infinity (records.writer.json_safe), beyond every limit either way
        condition = math.nan if ident.condition_number is None else ident.condition_number
        try:
            derived = Problem(int(trust_problems(
                acceptance, periods=ident.periods, settled=ident.settled, misfit=fit is not None and not fit.fits,
                condition_number=condition, aborted=aborted, ticks=record.timing.ticks,
                ticks_late_or_lost=record.timing.ticks_late + loop.ticks_lost,
                missed_replies=loop.missed_replies, stalls_cost_rows=record.schema_version >= STALL_ROWS_SCHEMA)))
        except (TypeError, ValueError):
            return []
    derived &= TRUST_PROBLEMS
    kept = problems & TRUST_PROBLEMS
    if derived == kept:
        return []
    return [f"its identification, timing and loop figures give the problems ({_names(derived)}) under its "
            f"variant's acceptance limits, but its problems list ({_names(kept)})"]


def _coil(record: Record) -> list[str]:
    """3: the coil's ``in_spec`` from its resistance at 20 degC and its spec, and the problem it makes."""
    from edc_bench.identification.coil_check import in_spec

    coil = record.coil
    if coil is None:
        return []
    found = []
    low, high = coil.spec_ohm
    if coil.resistance_20c_ohm is not None and coil.in_spec is not None:
        derived = in_spec(coil.resistance_20c_ohm, low, high)
        if derived is not None and derived != coil.in_spec:
            spec = f"{low if low is not None else ''}-{high if high is not None else ''} ohm"
            found.append(f"its coil's {coil.resistance_20c_ohm:.3f} ohm at 20 degC is "
                         f"{'within' if derived else 'out of'} its spec {spec}, but the record says "
                         f"{'in spec' if coil.in_spec else 'out of spec'}")
    problems = _problems(record)
    if problems is not None and record.schema_version >= PROBLEMS_SCHEMA \
            and (Problem.COIL_OUT_OF_SPEC in problems) != (coil.in_spec is False):
        found.append("its problems say 'coil out of spec' but its coil is in spec" if coil.in_spec is not False
                     else "its coil is out of spec but its problems do not say so")
    return found


def _part(record: Record) -> list[str]:
    """3 (the part): the problem 'pump fault' where, and only where, the part diagnosis did not judge the valve
    (schema 11 on)."""
    problems = _problems(record)
    if problems is None or record.schema_version < PART_SCHEMA or record.part is None:
        return []
    if (Problem.PUMP_FAULT in problems) == (not record.part.valve_judged):
        return []
    if record.part.valve_judged:
        return [f"its problems say 'pump fault' but its part diagnosis ({record.part.part}) judged the valve"]
    return [f"its part diagnosis names the {record.part.part} but its problems do not say 'pump fault'"]


def _limits(record: Record, c: ClassificationSummary) -> tuple[float, float] | None:
    """The classifier's threshold and marginal band as the record keeps them (None: it keeps neither)."""
    plane = record.decision_plane
    threshold = c.threshold if c.threshold is not None else (plane.threshold if plane is not None else None)
    band = c.marginal_band if c.marginal_band is not None else (plane.marginal_band if plane is not None else None)
    return None if threshold is None or band is None else (threshold, band)


def _classification(record: Record) -> list[str]:
    """4: the classifier's verdict from its P(faulty), distance, threshold and marginal band."""
    from edc_bench.verdict.classifier import verdicts_of

    c = record.classification
    limits = None if c is None else _limits(record, c)
    if c is None or limits is None or not math.isfinite(c.probability_faulty):
        return []
    threshold, band = limits
    faulty = c.probability_faulty >= threshold
    found = []
    distance = math.inf if c.distance is None else c.distance  # None: beyond the scan, on its verdict's side
    if c.distance is not None and c.distance != 0 and (c.distance > 0) != faulty:
        found.append(f"its classification's distance {c.distance:+.3f} puts the valve on the "
                     f"{'faulty' if c.distance > 0 else 'reusable'} side of the boundary, its P(faulty) "
                     f"{c.probability_faulty:.3f} on the other")
    expected = str(verdicts_of(c.probability_faulty, distance, threshold, band))
    if expected != c.verdict:
        shown = "beyond the scan" if c.distance is None else f"{c.distance:+.3f}"
        found.append(f"its classification says {c.verdict} but its figures give {expected} (P(faulty) "
                     f"{c.probability_faulty:.3f} against the threshold {threshold:g}, distance {shown} against "
                     f"the marginal band {band:g})")
    return found


def _close(a: float | None, b: float | None) -> bool:
    return a is None or b is None or not (math.isfinite(a) and math.isfinite(b)) \
        or math.isclose(a, b, rel_tol=SAME_REL, abs_tol=0.0)


def _figure(value: float | None) -> str:
    """A figure as a message shows it; a record's null as "none"."""
    return "none" if value is None else f"{value:.6g}"


def _features(record: Record) -> list[str]:
    """5: the relative features from the features and the baseline; the features from the parameters."""
    found = []
    af, a1 = record.features.af, record.features.a1
    params = {name: record.parameters[name].value for name in ("af", "a1") if name in record.parameters}
    if not (_close(af, params.get("af")) and _close(a1, params.get("a1"))):
        found.append(f"its features (af {_figure(af)}, a1 {_figure(a1)}) are not its identified parameters' "
                     f"(af {params.get('af')}, a1 {params.get('a1')})")
    c, base = record.classification, record.baseline
    if c is not None and base is not None and None not in (af, a1, base.af_v, base.a1_v_s_per_mm) \
            and base.af_v and base.a1_v_s_per_mm:
        rel = (af / base.af_v, a1 / base.a1_v_s_per_mm)  # as Baseline.relative gave the classifier
        kept = (c.features_rel.af, c.features_rel.a1)
        if not (_close(rel[0], kept[0]) and _close(rel[1], kept[1])):
            found.append(f"its classification's relative features (af x{kept[0]:.3f}, a1 x{kept[1]:.3f}) are not "
                         f"its features over its baseline (x{rel[0]:.3f}, x{rel[1]:.3f})")
    return found


def _model(record: Record) -> list[str]:
    """6: the model the record names, at its relative features; without the model, the decision plane."""
    from edc_bench.errors import ConfigError
    from edc_bench.verdict.classifier import default_classifier, find_model

    c = record.classification
    rel = None if c is None else (c.features_rel.af, c.features_rel.a1)
    if c is None or rel is None or None in rel or not all(math.isfinite(x) for x in rel):
        return []
    path = find_model(c.model_sha256) if c.model_sha256 else None
    if path is None:
        return _plane(record, c, rel)
    try:
        model = default_classifier(str(path))
        judged = model.classify(*rel)
    except ConfigError:
        return []  # the model cannot be loaded here: the record cannot be checked against it
    name = c.model_file or path.name
    if judged.verdict != c.verdict or abs(judged.probability_faulty - c.probability_faulty) > SAME_PROBABILITY:
        return [f"its model {name} gives {judged.verdict} at its relative features (af x{rel[0]:.3f}, a1 "
                f"x{rel[1]:.3f}; P(faulty) {judged.probability_faulty:.3f}), but its classification says "
                f"{c.verdict} (P(faulty) {c.probability_faulty:.3f})"]
    if (c.threshold is not None and c.threshold != model.threshold) \
            or (c.marginal_band is not None and c.marginal_band != model.marginal_band):
        return [f"its classification's threshold {c.threshold} and marginal band {c.marginal_band} are not its "
                f"model {name}'s ({model.threshold:g}, {model.marginal_band:g})"]
    return []


def _plane(record: Record, c: ClassificationSummary, rel: tuple[float, float]) -> list[str]:
    """6 without the model: the valve's side of the boundary in the decision plane, where its grid cell is all on
    one side (P(faulty) at each corner of the cell the valve is in)."""
    plane = record.decision_plane
    if plane is None or not plane.p_faulty:
        return []
    p = plane.p_faulty  # rows: a1, columns: af (ValveClassifier.boundary_grid)
    rows, cols = len(p), len(p[0])
    (af_lo, af_hi), (a1_lo, a1_hi) = plane.af_rel_range, plane.a1_rel_range
    if rows < 2 or cols < 2 or af_hi <= af_lo or a1_hi <= a1_lo:
        return []
    x = (rel[0] - af_lo) / (af_hi - af_lo) * (cols - 1)
    y = (rel[1] - a1_lo) / (a1_hi - a1_lo) * (rows - 1)
    if not (0 <= x <= cols - 1 and 0 <= y <= rows - 1):
        return []  # outside the plane
    j, i = min(int(x), cols - 2), min(int(y), rows - 2)
    corners = [p[i][j], p[i][j + 1], p[i + 1][j], p[i + 1][j + 1]]
    sides = {value >= plane.threshold for value in corners}
    if len(sides) != 1 or (c.probability_faulty >= plane.threshold) in sides:
        return []
    side = "faulty" if sides.pop() else "reusable"
    return [f"its decision plane puts the valve (af x{rel[0]:.3f}, a1 x{rel[1]:.3f}) on the {side} side of the "
            f"boundary, but its classification's P(faulty) {c.probability_faulty:.3f} on the other"]


def _retest(record: Record) -> list[str]:
    """7: a retest's decision from its verdict and the variant's ``[retest]`` rule as the test ran it."""
    from edc_bench.config.models import RetestSection
    from edc_bench.verdict.retest import decide

    retest = record.retest
    decided = (Verdict.PASS, Verdict.MARGINAL, Verdict.FAIL, Verdict.INVALID)  # what a retest can end with
    if retest is None or not retest.decision or record.verdict not in decided or not isinstance(record.config, dict) \
            or not isinstance(record.config.get("retest"), dict):
        return []
    try:
        decision = decide(record.verdict, RetestSection.model_validate(record.config["retest"]))
    except ValueError:
        return []
    if decision.verdict == retest.decision:
        return []
    return [f"its retest decides {retest.decision}, but its verdict {record.verdict} decides {decision.verdict} "
            f"by its variant's rule {decision.rule}"]


_CHECKS: tuple[Callable[[Record], list[str]], ...] = (_verdict, _trust, _coil, _part, _classification, _features,
                                                      _model, _retest)

__all__ = ["PROBLEMS_SCHEMA", "disagreements", "refusal"]
