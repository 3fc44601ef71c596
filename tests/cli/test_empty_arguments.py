"""An empty path or URL is refused in one line: ``--out ''`` had written into the current folder and ``--db ''``
had used the default history, neither said."""

from __future__ import annotations

import pytest

from edc_bench.cli import build_parser, main
from edc_bench.cli.common import given_path, history_url


def _flags_of_type(kind: object) -> list[tuple[str, str]]:
    commands = build_parser()._subparsers._group_actions[0].choices  # type: ignore[union-attr]
    return [(name, action.option_strings[-1] if action.option_strings else action.dest)
            for name, command in commands.items() for action in command._actions
            if action.type is kind and action.option_strings]


def test_every_path_and_url_flag_takes_the_checking_type() -> None:
    """No flag of any command is a bare ``pathlib.Path`` (which makes '' the current folder)."""
    from pathlib import Path

    assert _flags_of_type(Path) == []
    paths = _flags_of_type(given_path)
    assert ("test", "--out") in paths and ("report", "--out") in paths and len(paths) > 15
    assert {name for name, flag in _flags_of_type(history_url) if flag == "--db"} >= {"test", "history", "web",
                                                                                       "label", "session"}


@pytest.mark.parametrize(("argv", "says"), [
    (["test", "--out", ""], "an empty path: give a file or folder name"),
    (["test", "--out", "  "], "an empty path"),
    (["test", "--db", ""], "an empty URL: give sqlite:///FILE"),
    (["history", "--db", ""], "an empty URL"),
    (["report", ""], "an empty path"),
    (["session", "--out", ""], "an empty path"),
])
def test_an_empty_path_or_url_is_refused_in_one_line(argv: list[str], says: str,
                                                     capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exited:
        main(argv)
    out, err = capsys.readouterr()
    assert exited.value.code == 2 and out == ""
    assert says in err and err.count("\n") == 1, err
