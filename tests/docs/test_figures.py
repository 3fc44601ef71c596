"""The docs' generated figures are what the code prints now (docs/figures, ``python docs/regenerate.py``).

The default suite checks every page against the code and the stored measurements; the slow pass measures
every deterministic measurement again and checks the pages against the new results. Timings are not measured
again (a busy machine must not fail CI): they must be stored with the machine and the date.
"""

from __future__ import annotations

import re
import shutil
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
DOCS = ROOT / "docs"
sys.path.insert(0, str(DOCS))

import regenerate  # noqa: E402  (docs/regenerate.py)
from figures import common  # noqa: E402

REGISTRY = common.load_all()


@pytest.mark.slow  # over 5 s each: the default suite's 5 minutes (CI's slow pass runs it)
def test_every_page_says_what_the_code_prints(capsys):
    status = regenerate.run_cog(check=True)
    assert status == 0, "a page's generated figures are out of date (diff above): run `python docs/regenerate.py`"


@pytest.mark.parametrize("name", sorted(n for n, e in REGISTRY.items() if e.timing))
def test_a_timing_is_stored_with_its_machine_and_date(name):
    record = common.stored_record(name)
    assert record["measured"]["date"] and record["measured"]["machine"]
    assert common.measured_on(name).startswith(f"Measured on {record['measured']['date']}")


@pytest.mark.parametrize("name", sorted(n for n, e in REGISTRY.items() if not e.timing))
def test_a_deterministic_measurement_has_a_stored_result(name):
    assert "result" in common.stored_record(name)


def pages_reading(name: str) -> list[Path]:
    """The pages whose generated blocks import a figures module that reads the measurement ``name``."""
    readers = {module.stem for module in (DOCS / "figures").glob("*.py") if f'"{name}"' in module.read_text()}
    found = []
    for page in regenerate.pages():
        imported = set(re.findall(r"\[\[\[cog from figures import (\w+)", page.read_text()))
        if imported & readers:
            found.append(page)
    return found


@pytest.mark.parametrize("name", sorted(REGISTRY))
def test_every_measurement_is_printed_on_a_page(name):
    assert pages_reading(name), f"no page prints the measurement {name!r}"


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(n for n, e in REGISTRY.items() if not e.timing))
def test_measured_again_the_pages_still_hold(name, tmp_path, monkeypatch):
    """Measure ``name`` again into a copy of the stored results, and check the pages printing it against it."""
    shutil.copytree(common.DEFAULT_DATA_DIR, tmp_path / "data")
    monkeypatch.setenv("EDC_BENCH_DOCS_DATA", str(tmp_path / "data"))
    common.measure(name)
    status = regenerate.run_cog(check=True, only=pages_reading(name))
    assert status == 0, f"measured again, {name} no longer gives what the pages print (diff above)"


def test_a_changed_figure_fails_the_check_until_the_page_is_written_again(tmp_path, monkeypatch, capsys):
    """A deliberate change to the code behind a figure (the physics behind method.md's parameter table)
    makes the check fail on that page; written again, the page passes with the new figure."""
    from edc_bench.physics import feedforward

    truth = feedforward.feedforward_truth
    monkeypatch.setattr(feedforward, "feedforward_truth", lambda plant: truth(plant)._replace(af=truth(plant).af * 1.1))
    page = tmp_path / "method.md"
    shutil.copy(DOCS / "method.md", page)
    assert regenerate.run_cog(check=True, only=[page]) == 5
    assert "| af |" in capsys.readouterr().out  # the diff names the row that changed
    assert regenerate.run_cog(check=False, only=[page]) == 0
    assert regenerate.run_cog(check=True, only=[page]) == 0
    changed = [line for line in page.read_text().splitlines() if line.startswith("| af |")]
    assert changed and changed[0] not in (DOCS / "method.md").read_text()
