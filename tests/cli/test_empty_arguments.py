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


def test_every_flag_that_names_a_file_or_folder_refuses_an_empty_one() -> None:
    """Whatever its type (a path, or text such as '-' or 'shipped' beside a file): the review found --heads '' a
    traceback and --csv '' refused as '--csv .', a path never typed."""
    import argparse

    commands = build_parser()._subparsers._group_actions[0].choices  # type: ignore[union-attr]
    checked = []
    for name, command in commands.items():
        for action in command._actions:
            metavar = str(action.metavar or "")
            if not any(word in metavar for word in ("FILE", "DIR", "ONNX", "PATH")) or metavar.startswith("NAME"):
                continue  # a variant's NAME|PART|PATH is looked up by name first, and an empty one is refused so
            assert action.type is not None, f"{name} {action.option_strings}: a {metavar} taken as any text"
            try:
                action.type("")  # type: ignore[operator]
            except argparse.ArgumentTypeError:
                checked.append((name, action.option_strings[-1] if action.option_strings else action.dest))
                continue
            raise AssertionError(f"{name} {action.option_strings or action.dest} takes an empty {metavar}")
    assert ("history", "--heads") in checked and ("history", "--csv") in checked and ("train", "--adopt") in checked


def test_history_heads_into_a_folder_is_one_line(tmp_path: object, capsys: pytest.CaptureFixture[str]) -> None:
    """The review's finding: ``history --heads .`` was an OSError traceback, exit 70."""
    from edc_bench.history.store import HistoryStore

    url = f"sqlite:///{tmp_path}/h.sqlite"
    HistoryStore(url).close()
    code = main(["history", "--db", url, "--heads", str(tmp_path)])
    _, err = capsys.readouterr()
    assert code == 2 and err.count("\n") == 1 and "is a folder; give a file name" in err, err
