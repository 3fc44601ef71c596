"""A tampered record does not get in (#51): edited as an attacker would, its digests made anew or its schema lowered.

The integrity manifest's digests carry no secret (tests/records/test_integrity.py has the hand edits they catch).
Here record.json is edited and its manifest computed again with the project's own ``manifest()``, or its schema
lowered to one from before manifests and the manifest deleted: the record must then disagree with its own
figures (:mod:`edc_bench.records.consistency`), or say who wrote it (:func:`edc_bench.records.integrity.altered`).
"""

from __future__ import annotations

import json
import shutil
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
from helpers import edc_bench, rewrite_record_json

from edc_bench.bench import BenchOptions, run_bench_test, run_simulated_test
from edc_bench.config import load_variant, parse_variant
from edc_bench.cli.exit_codes import ExitCode
from edc_bench.errors import ConfigError
from edc_bench.records.consistency import disagreements
from edc_bench.records.reader import load_record
from edc_bench.records.record import write_record
from edc_bench.verdict.sections import RetestSummary
from edc_bench.verdict.verdicts import Verdict

Doc = dict[str, Any]


@pytest.fixture(scope="module")
def failed(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A worn valve's record: FAIL, P(faulty) 1.000, well outside the marginal band."""
    folder = write_record(run_simulated_test(load_variant(), "worn", 2), tmp_path_factory.mktemp("fail"),
                          figure=False)
    assert load_record(folder).verdict == Verdict.FAIL
    return folder


@pytest.fixture(scope="module")
def genuine(tmp_path_factory: pytest.TempPathFactory, failed: Path) -> dict[str, Path]:
    """A record of each verdict as the bench writes it: FAIL, PASS, a MARGINAL's retest, INVALID (aborted),
    UNCLASSIFIED, and a FAIL for a coil out of spec."""
    from conftest import simulated_bench_factory

    from edc_bench.testing.faults import FaultyBus, Rule

    out = tmp_path_factory.mktemp("genuine")
    variant = load_variant()
    retest = RetestSummary(of_record="first", of_verdict=Verdict.MARGINAL, decision=Verdict.FAIL,
                           words="near the limit twice: replace the valve", rule="retest.decide.MARGINAL = FAIL")
    folders = {"fail": failed,
               "pass": write_record(run_simulated_test(variant, "new", 3), out, figure=False),
               "marginal retested": write_record(run_simulated_test(variant, "clearance=0.185", 0), out,
                                                 figure=False, retest=retest),
               "unclassified": write_record(run_simulated_test(variant, "new", 1, classify=False), out,
                                            figure=False),
               "coil out of spec": write_record(run_simulated_test(variant, "new,coil_ohm=1.1", 3), out,
                                                figure=False)}
    short = variant.model_dump()
    short["excitation"]["duration_s"] = 8.0
    with simulated_bench_factory() as make:
        bench, clock, _ = make(parse_variant(short), "new", 3)
        aborted = run_bench_test(FaultyBus(bench, clock.now_s, [Rule("cut", 2.5)]), clock, parse_variant(short),
                                 BenchOptions(check_gains=False))
    folders["aborted"] = write_record(aborted, out, figure=False)
    return folders


def forged(folder: Path, tmp_path: Path, edit: Callable[[Doc], None], name: str = "rec") -> Path:
    """A copy of ``folder`` with record.json edited by ``edit`` and its manifest computed anew by the project's own
    ``manifest()``: the digests agree, as an attacker who read the code would make them."""
    copy = tmp_path / name
    shutil.copytree(folder, copy)
    doc = json.loads((copy / "record.json").read_text(encoding="utf-8"))
    edit(doc)
    rewrite_record_json(copy, doc)
    assert load_record(copy).schema_version == doc["schema"]  # the manifest holds: only the figures can tell
    return copy


def to_pass(doc: Doc) -> None:
    doc["verdict"] = "PASS"


def test_every_verdict_as_the_bench_writes_it_follows_from_its_own_figures(genuine: dict[str, Path]) -> None:
    verdicts = {kind: load_record(folder).verdict for kind, folder in genuine.items()}
    assert verdicts == {"fail": "FAIL", "pass": "PASS", "marginal retested": "MARGINAL", "unclassified": "UNCLASSIFIED",
                        "coil out of spec": "FAIL", "aborted": "INVALID"}
    for kind, folder in genuine.items():
        assert disagreements(load_record(folder)) == [], kind


def test_a_fail_made_pass_with_its_digests_made_anew_gets_no_report(failed: Path, tmp_path: Path) -> None:
    """The attack of #51: ``report`` drew a PASS report. It is refused as an altered record is (exit 2), naming
    what disagrees, and nothing is drawn."""
    folder = forged(failed, tmp_path, to_pass)
    proc = edc_bench("report", "rec", cwd=tmp_path)
    assert proc.returncode == 2, proc.stdout + proc.stderr
    message = proc.stderr.strip()
    assert len(message.splitlines()) == 1 and "Traceback" not in message
    assert "its verdict PASS does not follow from its own figures (the verdict is PASS but its classification " \
           "says FAIL)" in message
    assert "no report drawn" in message and "edc-bench replay rec" in message
    assert not (folder / "report.pdf").exists()


def test_classify_says_the_record_says_pass_and_exits_13(failed: Path, tmp_path: Path) -> None:
    forged(failed, tmp_path, to_pass)
    proc = edc_bench("classify", "rec", cwd=tmp_path)
    assert proc.returncode == 13, proc.stdout + proc.stderr
    lines = [line for line in proc.stdout.splitlines() if line.startswith("NOT as recorded")]
    assert len(lines) == 1 and proc.stdout.startswith("verdict: FAIL")
    assert "the record says PASS, classify says FAIL" in lines[0]
    assert "does not follow from its own figures (the verdict is PASS but its classification says FAIL)" in lines[0]
    out = json.loads(edc_bench("classify", "rec", "--json", cwd=tmp_path).stdout)
    assert (out["verdict"], out["recorded_verdict"]) == ("FAIL", "PASS") and out["not_as_recorded"] == lines[0]
    assert out["disagreements"] == ["the verdict is PASS but its classification says FAIL"]


def test_classify_of_a_genuine_record_says_nothing_more(genuine: dict[str, Path]) -> None:
    out = json.loads(edc_bench("classify", str(genuine["fail"]), "--json").stdout)
    assert out["recorded_verdict"] == out["verdict"] == "FAIL"
    assert out["not_as_recorded"] is None and out["disagreements"] == []


def test_classify_names_a_verdict_that_differs_for_a_reason_it_does_not_judge(genuine: dict[str, Path]) -> None:
    """Not every difference is a forgery: a coil out of spec fails a valve classify would pass. The line says
    both verdicts and why, and exits 13: a script never takes a PASS that its record calls FAIL for a plain one."""
    proc = edc_bench("classify", str(genuine["coil out of spec"]))
    assert proc.returncode == 13, proc.stdout + proc.stderr
    assert "NOT as recorded: the record says FAIL, classify says PASS (its coil is out of spec" in proc.stdout
    assert "does not follow" not in proc.stdout


def both(doc: Doc, **classification: Any) -> None:
    """The verdict made PASS, and the classification as the attacker would have it."""
    to_pass(doc)
    doc["classification"].update(classification)


@pytest.mark.parametrize(("edit", "named"), [
    (lambda d: both(d, verdict="PASS"), "its classification says PASS but its figures give FAIL (P(faulty) 1.000"),
    (lambda d: both(d, verdict="PASS", probability_faulty=0.1, distance=-0.4),
     "its model valve_mlp.onnx gives FAIL at its relative features"),
    (lambda d: both(d, verdict="PASS", probability_faulty=0.1, distance=-0.4, features_rel={"af": 1.0, "a1": 1.0}),
     "its classification's relative features (af x1.000, a1 x1.000) are not its features over its baseline"),
    (lambda d: (both(d, verdict="PASS", probability_faulty=0.1, distance=-0.4, features_rel={"af": 1.0, "a1": 1.0}),
                d["features"].update(af=d["baseline"]["af_v"], a1=d["baseline"]["a1_v_s_per_mm"])),
     "are not its identified parameters'"),
    (lambda d: d.update(verdict="INVALID"), "the verdict is INVALID but its classification says FAIL"),
    (lambda d: d.update(problems=["drifting"]), "the verdict is FAIL but its problems (drifting) make it INVALID"),
    (lambda d: d["coil"].update(in_spec=False), "is within its spec 0.6-0.9 ohm, but the record says out of spec"),
])
def test_a_deeper_forgery_is_named(failed: Path, tmp_path: Path, edit: Callable[[Doc], None], named: str) -> None:
    """Each figure the attacker edits to make the verdict agree leaves another that does not."""
    found = disagreements(load_record(forged(failed, tmp_path, edit)))
    assert any(named in line for line in found), found


def test_an_invalid_made_pass_is_named_by_the_trust_rule(genuine: dict[str, Path], tmp_path: Path) -> None:
    """An aborted test made PASS, its problems and reasons cleared: no classification to have judged it, and its
    loop figures still give the abort."""
    found = disagreements(load_record(forged(genuine["aborted"], tmp_path,
                                             lambda d: d.update(verdict="PASS", problems=[], reasons=[]))))
    assert found == ["the verdict is PASS but it holds no classification and no problem (a trustworthy test not "
                     "classified is UNCLASSIFIED)",
                     "its identification, timing and loop figures give the problems (aborted) under its variant's "
                     "acceptance limits, but its problems list (none)"]


def test_a_retest_s_decision_follows_from_its_verdict(genuine: dict[str, Path], tmp_path: Path) -> None:
    found = disagreements(load_record(forged(genuine["marginal retested"], tmp_path,
                                             lambda d: d["retest"].update(decision="PASS"))))
    assert found == ["its retest decides PASS, but its verdict MARGINAL decides FAIL by its variant's rule "
                     "retest.decide.MARGINAL = FAIL"]


def test_without_its_model_the_decision_plane_still_says(failed: Path, tmp_path: Path,
                                                         monkeypatch: pytest.MonkeyPatch) -> None:
    """On a station that lacks the model the record names, the decision plane it keeps places the valve."""
    import edc_bench.verdict.classifier as classifier

    record = load_record(forged(failed, tmp_path, lambda d: both(d, verdict="PASS", probability_faulty=0.1,
                                                                 distance=-0.4)))
    monkeypatch.setattr(classifier, "find_model", lambda sha256: None)
    found = disagreements(record)
    assert len(found) == 1 and found[0].startswith("its decision plane puts the valve (af x1.5")
    assert found[0].endswith("on the faulty side of the boundary, but its classification's P(faulty) 0.100 on the "
                             "other")


def lowered(doc: Doc) -> None:
    """The attack on the manifest itself: a schema from before manifests, and the manifest deleted."""
    to_pass(doc)
    doc["schema"] = 4
    del doc["integrity"]


def test_a_lowered_schema_without_its_manifest_is_altered(failed: Path, tmp_path: Path) -> None:
    """Schema 4 and no manifest: the record still holds what only a writer of manifests writes (its test_id, ...)."""
    folder = forged(failed, tmp_path, lambda d: None)
    doc = json.loads((folder / "record.json").read_text(encoding="utf-8"))
    lowered(doc)
    (folder / "record.json").write_text(json.dumps(doc), encoding="utf-8")
    with pytest.raises(ConfigError, match=r"changed after its test wrote it \(record.json's integrity manifest "
                                          r"\(removed: its schema says 4, but it holds 'test_id' and 'retest'"):
        load_record(folder)
    proc = edc_bench("report", "rec", cwd=tmp_path)
    assert proc.returncode == 2 and "integrity manifest (removed: its schema says 4" in proc.stderr


def test_a_later_edc_bench_version_says_it_wrote_a_manifest(failed: Path, tmp_path: Path) -> None:
    from edc_bench.records.integrity import MANIFEST_ERA_KEYS, altered

    doc = json.loads((failed / "record.json").read_text(encoding="utf-8"))
    lowered(doc)
    for path in MANIFEST_ERA_KEYS:  # every key of the manifest era removed: only the version is left to say
        *parents, key = path
        section = doc
        for name in parents:
            section = section[name]
        section.pop(key)
    assert altered(doc, failed) == []  # 0.1.0 wrote both kinds: the record alone cannot say (the history can)
    doc["software_version"] = "0.2.0.dev1"
    assert altered(doc, failed) == ["record.json's integrity manifest (removed: its schema says 4, but it holds "
                                    "software_version 0.2.0.dev1, written only by an edc-bench that writes a "
                                    "manifest)"]


def test_a_record_made_to_look_wholly_old_is_still_held_to_its_figures(failed: Path, tmp_path: Path) -> None:
    """The limit of the record alone: with every sign of its writer removed it reads as an old record; its verdict
    must still follow from its figures."""
    from edc_bench.records.integrity import MANIFEST_ERA_KEYS

    folder = tmp_path / "old"
    shutil.copytree(failed, folder)
    doc = json.loads((folder / "record.json").read_text(encoding="utf-8"))
    lowered(doc)
    for *parents, key in MANIFEST_ERA_KEYS:
        section = doc
        for name in parents:
            section = section[name]
        section.pop(key)
    (folder / "record.json").write_text(json.dumps(doc), encoding="utf-8")
    assert disagreements(load_record(folder)) == ["the verdict is PASS but its classification says FAIL"]


@pytest.mark.slow  # about 25 s: 20 simulated tests
def test_no_record_the_bench_writes_is_taken_for_a_forgery(tmp_path: Path) -> None:
    """The check must never refuse a genuine report: every kind of record (against the nominal baseline, on a
    variant not calibrated, a model that does not fit, beyond the classifier's scan, too short to converge) and
    the three variants' valves from new to faulty follow from their own figures."""
    out = tmp_path / "records"
    short = load_variant().model_dump()
    short["excitation"]["duration_s"] = 8.0
    renamed = load_variant().model_dump()
    renamed["pump"]["name"] = "a-pump-not-calibrated"
    misfit = load_variant("p-edc-hard").model_dump()
    misfit["coil"]["force_constant_variation_per_mm"] = 0.0667  # +/-30 % over the swing: the model cannot fit
    misfit["pump"]["name"] = "gain-test"
    results = [run_simulated_test(parse_variant(renamed), "new", 1, nominal_baseline=True, coil_temp_c=35.0),
               run_simulated_test(parse_variant(renamed), "worn", 1),
               run_simulated_test(parse_variant(misfit), "worn", 0, nominal_baseline=True),
               run_simulated_test(load_variant(), "clearance=0.5,roughness=2", 2),
               run_simulated_test(parse_variant(short), "new", 1, full_length=True)]
    results += [run_simulated_test(load_variant(name), valve, seed) for name in ("p-edc-default", "p-edc-hard",
                                                                                 "p-edc-long")
                for valve in ("new", "worn", "faulty", "clearance=0.185", "worn,coil_ohm=0.55") for seed in (4,)]
    verdicts = set()
    for result in results:
        record = load_record(write_record(result, out, figure=False))
        verdicts.add(record.verdict)
        assert disagreements(record) == [], (record.variant, record.valve_id, record.verdict, record.problems)
    assert verdicts >= {Verdict.PASS, Verdict.FAIL, Verdict.INVALID}


def test_classify_of_an_invalid_record_keeps_its_verdict_and_reasons(genuine: dict[str, Path]) -> None:
    """A model never judges a bad test: the record's INVALID and its reasons, said and printed as JSON."""
    folder = genuine["aborted"]
    record = load_record(folder)
    proc = edc_bench("classify", str(folder))
    assert proc.returncode == ExitCode.INVALID, proc.stdout + proc.stderr
    assert proc.stdout.splitlines()[0] == "verdict: INVALID" and "P(faulty)" not in proc.stdout
    assert all(f"  - {reason}" in proc.stdout for reason in record.reasons) and record.reasons
    out = json.loads(edc_bench("classify", str(folder), "--json").stdout)
    assert out == {"verdict": "INVALID", "reasons": list(record.reasons), "record_dir": str(folder),
                   "recorded_verdict": "INVALID", "not_as_recorded": None, "disagreements": [],
                   "not_as_first_indexed": None}


def test_a_forged_null_relative_feature_is_refused_in_one_line_not_a_traceback(failed: Path, tmp_path: Path) -> None:
    """A classification's relative features are figures: a null there (a forgery with its digests made anew) is
    refused naming the field, by classify, report and history --add (exit 2), never an internal error."""
    copy = tmp_path / "rec"
    shutil.copytree(failed, copy)
    doc = json.loads((copy / "record.json").read_text(encoding="utf-8"))
    doc["classification"]["features_rel"] = {"af": None, "a1": 5.0}
    rewrite_record_json(copy, doc)  # its manifest made anew: the digests agree
    for command in (("classify", "rec"), ("report", "rec"), ("history", "--add", "rec", "--db", "h.db")):
        proc = edc_bench(*command, cwd=tmp_path)
        assert proc.returncode == 2, (command, proc.stdout, proc.stderr)
        assert "Traceback" not in proc.stderr and "features_rel" in proc.stderr, (command, proc.stderr)
