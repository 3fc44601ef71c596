"""One decision everywhere (#53 item 3): `history` lists a line per valve visit, a retested MARGINAL's two tests on
one line with their decision; `--json` gives each test's visit decision; the trend counts a pair as one visit.

Before, `history` listed MARGINAL, MARGINAL and no decision (only `--csv` had it), and a pair was two visits."""

from __future__ import annotations

import json
import os
from pathlib import Path

from helpers import edc_bench

from edc_bench.history.rows import TestRow
from edc_bench.history.schema import COLUMNS
from edc_bench.history.store import HistoryStore
from edc_bench.history.visits import visits, with_visit_decisions


def _row(n: int, valve: str, verdict: str, started: str, retest_of: str | None = None,
         decision: str | None = None) -> dict:
    row = {name: "" for name in COLUMNS if name not in ("id", "record_sha256", "indexed_at", "indexed_by")}
    row.update(record_dir=f"/records/r{n}", started_at=started, valve_id=valve, verdict=verdict, af_v=0.1,
               a1_v_s_per_mm=0.01, af_rel=1.2, a1_rel=1.4, probability_faulty=None, distance=None, model_name=None,
               model_sha256=None, coil_r20_ohm=None, coil_in_spec=None, model_fits=None, stop_reason=None,
               test_s=None, simulated=None, retest_of=retest_of, decision=decision)
    return row


def test_a_retest_joins_its_first_test_in_one_visit_with_the_pairs_decision() -> None:
    rows = [{**_row(1, "V1", "MARGINAL", "2026-11-27T08:00:00+00:00"), "id": 1},
            {**_row(2, "V2", "PASS", "2026-11-27T08:01:00+00:00"), "id": 2},
            {**_row(3, "V1", "MARGINAL", "2026-11-27T08:02:00+00:00", "/records/r1", "FAIL"), "id": 3},
            {**_row(4, "V3", "MARGINAL", "2026-11-27T08:03:00+00:00", "/records/gone", "PASS"), "id": 4}]
    rows = [TestRow.of(row) for row in rows]
    shown = visits(rows)
    assert [(v.ids, v.verdicts, v.decision) for v in shown] == [
        ("1+3", "MARGINAL then MARGINAL", "FAIL"), ("2", "PASS", "PASS"),
        ("4", "MARGINAL", "PASS")]  # a retest whose first test is not listed stands alone, with its decision
    marked = with_visit_decisions(rows)
    assert [(r["id"], r["visit_decision"], r["visit"]) for r in marked] == [
        (1, "FAIL", [1, 3]), (2, "PASS", [2]), (3, "FAIL", [1, 3]), (4, "PASS", [4])]


def test_history_lists_a_pair_as_one_visit_with_its_decision_and_json_gives_it(tmp_path: Path) -> None:
    url = f"sqlite:///{tmp_path / 'h.sqlite'}"
    with HistoryStore(url) as store:
        store.add_row(_row(1, "V1", "MARGINAL", "2026-11-27T08:00:00+00:00"))
        store.add_row(_row(2, "V1", "MARGINAL", "2026-11-27T08:00:30+00:00", "/records/r1", "FAIL"))
        store.add_row(_row(3, "V1", "PASS", "2026-11-28T08:00:00+00:00"))
    env = {**os.environ, "COLUMNS": "200"}
    listing = edc_bench("history", "--db", url, env=env)
    assert listing.returncode == 0, listing.stderr
    flat = " ".join(listing.stdout.split())
    assert "2 visit(s), 3 test(s)" in flat, listing.stdout
    assert "MARGINAL then MARGINAL │ FAIL" in flat and "1+2" in flat, listing.stdout
    assert "PASS │ PASS" in flat
    rows = json.loads(edc_bench("history", "--json", "--db", url, env=env).stdout)
    assert [(r["verdict"], r["decision"], r["visit_decision"]) for r in rows] == [
        ("MARGINAL", None, "FAIL"), ("MARGINAL", "FAIL", "FAIL"), ("PASS", None, "PASS")]
    trend = " ".join(edc_bench("history", "--trend", "V1", "--db", url, env=env).stdout.split())
    assert "valve V1: 2 visit(s)" in trend and "MARGINAL then MARGINAL │ FAIL" in trend, trend
    plot = tmp_path / "trend.png"
    assert edc_bench("history", "--trend", "V1", "--plot", str(plot), "--db", url, env=env).returncode == 0
    assert plot.is_file()


def test_at_80_columns_the_listing_keeps_the_visit_and_its_decision_whole() -> None:
    """A technician's terminal of 80 columns: the decision and the whole ids, never a table cut at the edge."""
    from rich.console import Console

    from edc_bench.cli.history_cmd import history_table

    long_id = "V-2040-REWORKED-BY-BOSCH-SERVICE-0042"
    rows = [{**_row(1, long_id, "MARGINAL", "2026-11-27T08:00:00+00:00"), "id": 1, "station": "bench-2",
             "operator": "m.keller", "variant": "p-edc-default", "changes": 0},
            {**_row(2, long_id, "MARGINAL", "2026-11-27T08:01:00+00:00", "/records/r1", "FAIL"), "id": 2,
             "station": "bench-2", "operator": "m.keller", "variant": "p-edc-default", "changes": 0}]
    for width in (80, 120, 200):
        console = Console(width=width, record=True, color_system=None)
        history_table([TestRow.of(row) for row in rows], "sqlite:///h.sqlite", console)
        text = console.export_text()
        assert max(len(line) for line in text.splitlines()) <= width, text
        valve_column = "".join(line.split("│")[3].strip() for line in text.splitlines() if line.startswith("│"))
        assert valve_column == long_id and "FAIL" in text and "MARGINAL" in text, text
        assert ("bench-2" in text) == (width >= 100), text


def test_the_trend_plot_shows_each_visit_against_the_limit_and_the_marginal_band(tmp_path: Path) -> None:
    """#53 item 8: the trend plot had no limit line and no verdicts; a pair counted as two visits."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from edc_bench.cli import history_cmd
    from edc_bench.history import trend_plot

    rows = []
    for n, (verdict, distance, day, retest_of, decision) in enumerate((
            ("PASS", -0.4, "2026-03-02", None, None), ("PASS", -0.1, "2026-06-01", None, None),
            ("MARGINAL", 0.01, "2026-09-01", None, None), ("MARGINAL", 0.02, "2026-09-01", "/records/r3", "FAIL")),
            start=1):
        row = {**_row(n, "V1", verdict, f"{day}T08:00:{n:02d}+00:00", retest_of, decision), "id": n,
               "distance": distance, "variant": "p-edc-default"}
        rows.append(TestRow.of(row))
    drawn = []
    original = plt.Figure.savefig

    def keep(fig, *args, **kwargs):
        drawn.append(fig)
        return original(fig, *args, **kwargs)

    plt.Figure.savefig = keep
    try:
        history_cmd._plot(visits(rows), "V1", tmp_path / "trend.png")
    finally:
        plt.Figure.savefig = original
    (fig,) = drawn
    _, limit_ax = fig.axes[:2]
    labels = limit_ax.get_legend_handles_labels()[1]
    band = trend_plot.marginal_band("p-edc-default")
    assert band is not None and 0 < band < 0.5
    assert labels == ["limit: FAIL above", f"marginal band (+/-{band:g})"]
    xs, ys = limit_ax.lines[0].get_data()
    assert list(xs) == [1, 2, 3] and list(ys) == [-0.4, -0.1, 0.02]  # a visit a point; the pair's deciding test
    assert [t.get_text() for t in fig.axes[0].texts] == ["PASS", "PASS", "FAIL"]
    assert (tmp_path / "trend.png").stat().st_size > 10_000
    assert trend_plot.marginal_band("a-variant-this-station-lacks") is None  # the limit alone, no traceback
