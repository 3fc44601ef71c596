"""One decision everywhere (#53 item 3): a MARGINAL's report names what it and its retest decide.

Before, a MARGINAL retested MARGINAL was decided FAIL, the retest's report said FAIL, and the first test's report
said only "retest"; both charts' legends said "this valve: MARGINAL".
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest
from helpers import run_cli

from edc_bench.records.reader import load_record, load_trace
from edc_bench.records.report import draw_report, report_pages
from edc_bench.records.retest_link import find_retest


@pytest.fixture(scope="module")
def pair(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """A MARGINAL retested MARGINAL by `edc-bench test`: the first test's folder and the retest's."""
    out = tmp_path_factory.mktemp("pair")
    capsys = _Capture()
    code, stdout, _ = run_cli(["test", "--valve", "clearance=0.185", "--no-figure", "--no-history", "--json",
                               "--out", str(out)], capsys)
    assert code == 11, stdout  # the pair decides FAIL
    first, second = sorted(out.iterdir())
    assert load_record(second).retest.of_record == first.name
    return first, second


class _Capture:
    """capsys for a module-scoped fixture: run_cli reads what was printed."""

    def readouterr(self) -> tuple[str, str]:
        return "", ""


def _page_1_words(folder: Path) -> tuple[str, str]:
    record = load_record(folder)
    link = find_retest(folder, record)
    if link is not None:
        record = record.model_copy(update={"retested_by": link})
    page = report_pages(record, load_trace(folder), folder.name)[0]
    text = " ".join(" ".join(t.get_text().split()) for t in page.figure.texts)
    legend = " ".join(t.get_text() for legend in page.figure.legends for t in legend.get_texts())
    return text, legend


def test_the_first_tests_report_gives_the_pairs_decision_and_names_the_retest(pair: tuple[Path, Path]) -> None:
    first, second = pair
    link = find_retest(first, load_record(first))
    assert link is not None and (link.record, link.verdict, link.decision) == (second.name, "MARGINAL", "FAIL")
    text, legend = _page_1_words(first)
    assert "FAIL" in text and "Near the limit twice: replace the valve." in text, text
    assert f"retest (record {second.name}); together they decide FAIL" in text, text
    assert "Near the limit: retest." not in text
    assert "this valve: MARGINAL (tested twice: FAIL)" in legend, legend
    retest_text, retest_legend = _page_1_words(second)
    assert "FAIL" in retest_text and "together they decide FAIL" in retest_text
    assert "this valve: MARGINAL (tested twice: FAIL)" in retest_legend
    pdf, _ = draw_report(first)  # as the session and `edc-bench report` draw it
    assert pdf.is_file()


def test_only_the_retest_that_names_the_test_is_its_retest(pair: tuple[Path, Path], tmp_path: Path) -> None:
    first, second = pair
    assert find_retest(second, load_record(second)) is None  # the retest is no first test
    shop = tmp_path / "records"
    shop.mkdir()
    copied = shutil.copytree(first, shop / first.name)
    assert find_retest(copied, load_record(copied)) is None  # its retest is not beside it
    # a later folder of the same valve that is the retest of another test is not this one's
    other = shutil.copytree(second, shop / second.name)
    doc = json.loads((other / "record.json").read_text())
    doc["retest"]["of_record"] = "20261127T000000+0000-p-edc-default-clearance_0.185"
    (other / "record.json").write_text(json.dumps(doc))
    assert find_retest(copied, load_record(copied)) is None


def test_the_retest_is_found_from_the_folder_itself_and_across_a_change_of_summer_time(
        pair: tuple[Path, Path], tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    first, second = pair
    monkeypatch.chdir(first)
    assert find_retest(Path("."), load_record(first)) is not None  # `edc-bench report .`
    # at the end of summer time a test at 02:50 +0200 and its retest at 02:05 +0100: the retest's name sorts first
    shop = tmp_path / "records"
    shop.mkdir()
    before = shutil.copytree(first, shop / "20261025T025000+0200-p-edc-default-clearance_0.185")
    after = shutil.copytree(second, shop / "20261025T020500+0100-p-edc-default-clearance_0.185")
    doc = json.loads((after / "record.json").read_text())
    doc["retest"]["of_record"] = before.name
    (after / "record.json").write_text(json.dumps(doc))
    found = find_retest(before, load_record(before))
    assert found is not None and found.record == after.name


def test_a_retest_started_in_the_same_second_as_its_test_is_a_test_of_its_own_in_the_history(
        pair: tuple[Path, Path], tmp_path: Path) -> None:
    """A simulated test takes less than a second: CI's session soak found 298 history rows for 300 tests, the
    retests that started in their first test's second taken for that test indexed again (same when, valve, pump
    and station). The retest's key names its first test."""
    from edc_bench.history.store import HistoryStore, row_from_record

    first, second = pair
    first_record, second_record = load_record(first), load_record(second)
    same_second = second_record.model_copy(update={"started_at": first_record.started_at})
    with HistoryStore(f"sqlite:///{tmp_path / 'h.sqlite'}") as store:
        assert store.add_row(row_from_record(first_record, first)) == "new"
        assert store.add_row(row_from_record(same_second, second)) == "new"
        rows = store.list()
    assert [(r.verdict, r.decision) for r in rows] == [("MARGINAL", None), ("MARGINAL", "FAIL")]
