"""The report (`edc-bench report`): a two-page PDF and a PNG per page, for a judged and for an aborted test; the
date in local time. What each page says, and that no text leaves its box: test_report_layout.py."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from edc_bench.bench import BenchOptions, run_bench_test, run_simulated_test
from edc_bench.config import load_variant
from edc_bench.records.record import write_record
from edc_bench.records.schema import Identity
from edc_bench.testing.faults import FaultyBus, Rule


def _aborted_record(tmp_path: Path, simulated_bench) -> Path:
    variant = load_variant()
    bench, clock, _ = simulated_bench(variant, "new", 3)
    result = run_bench_test(FaultyBus(bench, clock.now_s, [Rule("cut", 4.0)]), clock, variant,
                            BenchOptions(check_gains=False))
    assert result.verdict == "INVALID"
    return write_record(result, tmp_path / "aborted", figure=False)


@pytest.mark.parametrize("kind", ["fail", "invalid"])
def test_report_is_a_two_page_pdf_and_a_png_per_page(tmp_path: Path, kind: str, simulated_bench) -> None:
    if kind == "fail":
        result = run_simulated_test(load_variant(), "worn", 2,
                                    identity=Identity(pump_serial="P-9", station="bench-1", operator="jo"))
        folder = write_record(result, tmp_path, figure=False)
    else:
        folder = _aborted_record(tmp_path, simulated_bench)
    proc = subprocess.run([sys.executable, "-m", "edc_bench", "report", str(folder), "--out", str(tmp_path / "r")],
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    out = tmp_path / "r"
    assert proc.stdout.splitlines() == [f"report: {out / 'report.pdf'}",
                                        f"page images: {out / 'report-page.png'}, {out / 'report-page-2.png'}"]
    pdf = (out / "report.pdf").read_bytes()
    assert pdf.startswith(b"%PDF") and b"/Type /Pages" in pdf and b"/Count 2" in pdf
    for name in ("report-page.png", "report-page-2.png"):  # page 1 keeps the name it had when it was the only one
        assert (out / name).read_bytes()[:4] == b"\x89PNG"


def test_report_bad_input(tmp_path: Path) -> None:
    proc = subprocess.run([sys.executable, "-m", "edc_bench", "report", str(tmp_path)], capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 2 and "no record.json" in proc.stderr and "Traceback" not in proc.stderr


def test_the_convergence_plot_shows_the_period_fit_the_verdict_comes_from(tmp_path: Path) -> None:
    """On p-edc-hard the online estimates differ from the period fit by tens of per cent: the plot shows both."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from edc_bench.records.reader import load_record, load_trace
    from edc_bench.records.report_plots import draw_convergence, reference_values

    folder = write_record(run_simulated_test(load_variant("p-edc-hard"), "worn", 0), tmp_path, figure=False)
    record, trace = load_record(folder), load_trace(folder)
    fig, ax = plt.subplots()
    draw_convergence(ax, trace, record)
    lines = {line.get_label(): line for line in ax.get_lines()}
    spans = {c.get_label(): c for c in ax.collections if "period fit" in c.get_label()}
    plt.close(fig)
    for name in ("af", "a1"):
        (segment,) = spans.pop(f"{name}, period fit over 3 periods (the feature)").get_segments()
        (t0, y0), (t1, y1) = segment
        assert t1 == pytest.approx(trace["t_s"][-1]) and t1 - t0 == pytest.approx(6.0)  # 3 periods of 2 s
        assert y0 == y1 == pytest.approx(record.parameters[name].value / reference_values(record)[name][0])
        online = lines[f"{name} / baseline, online"].get_ydata()[-1]
        assert abs(online - y0) > 0.05 * y0, (name, online, y0)  # it is not the online estimate
    assert not spans


@pytest.mark.parametrize(("zone", "shown"), [("CET-1", "2026-11-26 11:04 (UTC+01:00)"),
                                              ("IST-5:30", "2026-11-26 15:34 (UTC+05:30)"),
                                              ("EST+5", "2026-11-26 05:04 (UTC-05:00)"),
                                              ("UTC0", "2026-11-26 10:04 (UTC+00:00)")])
def test_the_date_is_the_local_time_of_the_machine_drawing_the_report_with_its_offset(time_zone, zone: str,
                                                                                     shown: str) -> None:
    from edc_bench.records.report_content import local_time, utc_time

    time_zone(zone)
    assert local_time("2026-11-26T10:04:00+00:00") == shown
    assert utc_time("2026-11-26T11:04:30+01:00") == "2026-11-26 10:04:30 UTC"
    assert local_time("not a date") == "not a date" and local_time("") == "not recorded"
