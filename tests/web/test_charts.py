"""The chain page's chart of tests per day: laid out by set margins (not cropped to what is drawn), so a station's
long name is cut to the legend's room rather than pushed out of the picture."""

from __future__ import annotations

import base64

from edc_bench.history.summary import DayCount
from edc_bench.web import charts


def _svg(data_url: str) -> str:
    return base64.b64decode(data_url.split(",", 1)[1]).decode("utf-8")


def test_a_long_station_name_is_cut_to_the_legends_room() -> None:
    long_name = "Werkstatt Nord-Ost Station 12 (Halle B)"
    days = tuple(DayCount(f"2026-11-{d:02d}", name, 5 + d) for d in range(1, 8)
                 for name in (long_name, "Station $x$ 42"))
    chart = charts.tests_per_day(days)
    assert chart is not None
    svg = _svg(chart)
    cut = long_name[:charts.LEGEND_CHARACTERS - 1] + "\u2026"
    assert f"<!-- {cut} -->" in svg and long_name not in svg
    assert "<!-- Station $x$ 42 -->" in svg  # as typed: no formula
    assert 'width="576pt"' in svg  # the figure's own 8 inches: nothing outside it was drawn


def test_long_names_that_begin_alike_are_told_apart_in_the_legend() -> None:
    names = ("Werkstatt Nord-Ost Station 12 (Halle A)", "Werkstatt Nord-Ost Station 12 (Halle B)")
    chart = charts.tests_per_day(tuple(DayCount("2026-11-02", name, 3 + k) for k, name in enumerate(names)))
    assert chart is not None
    labels = [line[5:-4] for line in _svg(chart).splitlines() if line.strip().startswith("<!-- Werkstatt")]
    assert len(labels) == 2 and len(set(labels)) == 2, labels


def test_no_tests_no_chart() -> None:
    assert charts.tests_per_day(()) is None
