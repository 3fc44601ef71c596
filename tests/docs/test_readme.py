"""README.md is what a newcomer reads in five minutes: at most about 8 KB, and it says what the first hour needs
(the tester's finding: 32 KB, of which about 6 were what a newcomer needs, and prerequisites, sizes, the extras the
slow commands need and where files go were missing up front). Its commands run verbatim in
tests/structure/test_readme_commands.py (slow)."""

from __future__ import annotations

from helpers import REPO

README = (REPO / "README.md").read_text(encoding="utf-8")


def test_the_readme_is_read_in_five_minutes() -> None:
    assert len(README.encode("utf-8")) <= 8_500


def test_the_readme_says_what_the_first_hour_needs() -> None:
    for said in ("## Before you start", "python3-venv", "GB for the virtual environment", "MB for each test's record",
                 "## Quick start", "## A tour of the station", "## Verdicts and what to do", "Exit codes: 0 PASS",
                 "## Where files go", '".[train]"', "not judged: the PC stalled", "docs/commands.md",
                 "docs/architecture.md"):
        assert said in README, said


def test_every_page_the_readme_names_exists() -> None:
    import re

    for page in set(re.findall(r"`((?:docs|firmware_proto)/[\w/.-]+\.md)`", README)):
        assert (REPO / page).is_file(), page
