"""The MARGINAL procedure: a MARGINAL is tested again at once, and the variant's [retest] rule decides the pair."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from helpers import edc_bench

from edc_bench.config.models import RetestSection
from edc_bench.history.store import HistoryStore
from edc_bench.records.reader import load_record
from edc_bench.verdict.retest import decide, retest_wanted
from edc_bench.verdict.verdicts import Verdict

# a valve inside the default variant's marginal band, MARGINAL with noise seeds 0 and 1
NEAR_THE_LIMIT = "clearance=0.185"


@pytest.mark.parametrize(("second", "verdict", "words"), [
    ("PASS", "PASS", "near the limit then clear of it: refit the valve"),
    ("MARGINAL", "FAIL", "near the limit twice: replace the valve"),
    ("FAIL", "FAIL", "near the limit then worn: replace the valve"),
    ("INVALID", "INVALID", "near the limit then not judged: check the cable; then test the valve again"),
])
def test_the_default_rule_decides_every_pair(second: str, verdict: str, words: str) -> None:
    decision = decide(second, RetestSection(), check_words="not judged: check the cable")
    assert decision.verdict == Verdict(verdict)
    assert decision.words == words
    assert decision.rule == f"retest.decide.{second} = {verdict}"


def test_only_a_marginal_is_retested_and_a_variant_may_say_not() -> None:
    rule = RetestSection()
    assert [v for v in Verdict if retest_wanted(v, rule)] == [Verdict.MARGINAL]
    assert not retest_wanted("MARGINAL", RetestSection(after_marginal=False))


def test_a_variant_may_be_lenient_on_a_second_marginal() -> None:
    rule = RetestSection(decide={"PASS": "PASS", "MARGINAL": "PASS", "FAIL": "FAIL", "INVALID": "INVALID"})
    assert decide("MARGINAL", rule).words == "near the limit twice: refit the valve"


@pytest.mark.parametrize(("decide_table", "message"), [
    ({"PASS": "PASS", "FAIL": "FAIL", "INVALID": "INVALID"}, "missing MARGINAL"),
    ({"PASS": "PASS", "MARGINAL": "INVALID", "FAIL": "FAIL", "INVALID": "INVALID"}, "decide.MARGINAL must be"),
    ({"PASS": "PASS", "MARGINAL": "FAIL", "FAIL": "FAIL", "INVALID": "PASS"}, "decide.INVALID must be"),
])
def test_a_rule_that_leaves_a_valve_undecided_is_refused(decide_table: dict[str, str], message: str) -> None:
    with pytest.raises(ValueError, match=message):
        RetestSection(decide=decide_table)


def test_a_bad_retest_section_in_a_variant_file_is_one_clear_line(tmp_path: Path) -> None:
    from helpers import REPO

    source = (REPO / "configs" / "p-edc-default.toml").read_text()
    bad = tmp_path / "lenient.toml"
    bad.write_text(source.replace('name = "p-edc-default"', 'name = "lenient"')
                   + '\n[retest]\ndecide = { PASS = "PASS", MARGINAL = "INVALID", FAIL = "FAIL", INVALID = "INVALID" }\n')
    proc = edc_bench("test", "--variant", str(bad), "--no-history", cwd=tmp_path)
    assert proc.returncode == 2, proc.stderr
    assert "decide.MARGINAL must be" in proc.stderr and "Traceback" not in proc.stderr


def test_a_marginal_is_retested_and_the_pair_decides(tmp_path: Path) -> None:
    db = tmp_path / "history.sqlite"
    proc = edc_bench("test", "--valve", NEAR_THE_LIMIT, "--valve-id", "V-185", "--out", "rec", "--no-figure",
                     "--plain", "--db", f"sqlite:///{db}", cwd=tmp_path)
    assert proc.returncode == 11, proc.stderr  # two MARGINALs: FAIL, replace
    out = proc.stdout
    assert out.count("verdict: MARGINAL, near the limit: retest") == 2
    assert "retest: MARGINAL is near the limit; the bench tests the valve again now (simulated rig: noise seed 1)" in out
    assert "decision: FAIL, near the limit twice: replace the valve" in out
    first_dir, second_dir = sorted((tmp_path / "rec").iterdir())
    first, second = load_record(first_dir), load_record(second_dir)
    assert first.retest is None and first.simulation.seed == 0
    assert second.simulation.seed == 1  # new noise on the simulated rig
    assert second.retest is not None
    assert (second.retest.of_record, second.retest.of_verdict) == (first_dir.name, "MARGINAL")
    assert (second.retest.decision, second.retest.rule) == ("FAIL", "retest.decide.MARGINAL = FAIL")
    # the retest's report gives the customer the pair's decision, and says the valve was tested twice
    from edc_bench.records import report_content

    assert report_content.shown_verdict(second) == "FAIL" and report_content.shown_verdict(first) == "MARGINAL"
    assert report_content.advice_sentence(second) == "Near the limit twice: replace the valve."
    assert report_content.findings(second)[0].startswith("Tested twice: MARGINAL (near the limit), then MARGINAL")
    rows = {Path(row.record_dir).name: row for row in HistoryStore(f"sqlite:///{db}").list()}
    assert rows[first_dir.name].retest_of is None and rows[first_dir.name].decision is None
    assert Path(rows[second_dir.name].retest_of).name == first_dir.name
    assert rows[second_dir.name].decision == "FAIL"


@pytest.mark.slow  # the default suite's 5 minutes; CI's slow pass runs it
def test_the_json_summary_of_a_retest_holds_both_tests_and_the_decision(tmp_path: Path) -> None:
    proc = edc_bench("test", "--valve", NEAR_THE_LIMIT, "--out", "rec", "--no-figure", "--json", "--no-history",
                     cwd=tmp_path)
    assert proc.returncode == 11, proc.stderr
    summary = json.loads(proc.stdout)  # one JSON document
    assert summary["decision"] == {"verdict": "FAIL", "words": "near the limit twice: replace the valve",
                                   "rule": "retest.decide.MARGINAL = FAIL"}
    assert summary["first_test"]["verdict"] == "MARGINAL" and summary["verdict"] == "MARGINAL"
    assert summary["first_test"]["record_dir"] != summary["record_dir"]


@pytest.mark.slow  # the default suite's 5 minutes; CI's slow pass runs it
def test_no_retest_leaves_a_marginal_to_the_technician(tmp_path: Path) -> None:
    proc = edc_bench("test", "--valve", NEAR_THE_LIMIT, "--out", "rec", "--no-figure", "--plain", "--no-history",
                     "--no-retest", cwd=tmp_path)
    assert proc.returncode == 10, proc.stderr
    assert "retest:" not in proc.stdout and len(list((tmp_path / "rec").iterdir())) == 1
