"""The one-page report (`edc-bench report`): one PDF page and a PNG, for a judged and for an aborted test."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from edc_bench.bench import BenchOptions, run_bench_test, run_simulated_test
from edc_bench.config import load_variant
from edc_bench.records.record import write_record
from edc_bench.testing.faults import FaultyBus, Rule


def _aborted_record(tmp_path: Path, simulated_bench) -> Path:
    variant = load_variant()
    bench, clock, _ = simulated_bench(variant, "new", 3)
    result = run_bench_test(FaultyBus(bench, clock.now_s, [Rule("cut", 4.0)]), clock, variant,
                            BenchOptions(check_gains=False))
    assert result.verdict == "INVALID"
    return write_record(result, tmp_path / "aborted", figure=False)


@pytest.mark.parametrize("kind", ["fail", "invalid"])
def test_report_is_one_pdf_page_and_a_png(tmp_path: Path, kind: str, simulated_bench) -> None:
    if kind == "fail":
        result = run_simulated_test(load_variant(), "worn", 2,
                                    identity={"pump_serial": "P-9", "station": "bench-1", "operator": "jo"})
        folder = write_record(result, tmp_path, figure=False)
    else:
        folder = _aborted_record(tmp_path, simulated_bench)
    proc = subprocess.run([sys.executable, "-m", "edc_bench", "report", str(folder), "--out", str(tmp_path / "r")],
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    pdf = (tmp_path / "r" / "report.pdf").read_bytes()
    assert pdf.startswith(b"%PDF") and pdf.count(b"/Type /Page\n") + pdf.count(b"/Type /Page ") <= 1
    assert b"/Type /Pages" in pdf and b"/Count 1" in pdf
    png = (tmp_path / "r" / "report-page.png").read_bytes()
    assert png[:4] == b"\x89PNG"


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
    from edc_bench.records.report import _convergence, _reference_values

    folder = write_record(run_simulated_test(load_variant("p-edc-hard"), "worn", 0), tmp_path, figure=False)
    record, trace = load_record(folder), load_trace(folder)
    fig, ax = plt.subplots()
    _convergence(ax, trace, record)
    lines = {line.get_label(): line for line in ax.get_lines()}
    spans = {c.get_label(): c for c in ax.collections if "period fit" in c.get_label()}
    plt.close(fig)
    for name in ("af", "a1"):
        (segment,) = spans.pop(f"{name}, period fit over 3 periods (the feature)").get_segments()
        (t0, y0), (t1, y1) = segment
        assert t1 == pytest.approx(trace["t_s"][-1]) and t1 - t0 == pytest.approx(6.0)  # 3 periods of 2 s
        assert y0 == y1 == pytest.approx(record.parameters[name].value / _reference_values(record)[name][0])
        online = lines[f"{name} / baseline, online"].get_ydata()[-1]
        assert abs(online - y0) > 0.05 * y0, (name, online, y0)  # it is not the online estimate
    assert not spans
