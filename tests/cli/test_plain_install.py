"""On the plain install (no extras): a command that needs an extra says which, in one line, before any work; a
numeric flag out of its range is refused; a web port that cannot be served is one line, not a URL and a traceback.

The tester's findings: ``edc-bench paper`` exited 70 after 82 s (``No module named 'skl2onnx'``); ``edc-bench web
--port 99999`` printed its URL, then exited 70 with ``OverflowError: bind(): port must be 0-65535``.
"""

from __future__ import annotations

import socket
from pathlib import Path

import pytest

import edc_bench.cli.common as common
from edc_bench.cli import build_parser, main
from edc_bench.cli.exit_codes import ExitCode


def _cli(argv: list[str]) -> int:
    """``edc-bench ARGV``'s exit code (argparse's refusals exit from inside the parser)."""
    try:
        return main(argv)
    except SystemExit as exc:
        return int(exc.code or 0)


@pytest.fixture()
def without_the_train_extra(monkeypatch: pytest.MonkeyPatch) -> None:
    """As if scikit-learn, skl2onnx and onnx were not installed (the modules looked for are ones that are not)."""
    monkeypatch.setitem(common.EXTRAS, "train", {"edc_bench_no_such_module_sklearn": "scikit-learn",
                                                 "edc_bench_no_such_skl2onnx": "skl2onnx"})


@pytest.mark.parametrize("argv", [["paper"], ["paper", "--runs", "3"], ["train", "--variants", "p-edc-default"]],
                         ids=["paper", "paper-runs", "train"])
def test_a_command_that_needs_the_train_extra_says_so_before_any_work(
        argv: list[str], without_the_train_extra: None, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    import edc_bench.experiments.studies as studies

    def no_work(*args: object, **kwargs: object) -> None:
        raise AssertionError("the experiment started before the missing extra was said")

    monkeypatch.setattr(studies, "paper_experiment", no_work)
    code = _cli(argv)
    out, err = capsys.readouterr()
    assert code == ExitCode.BAD_INPUT, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "needs the 'train' extra" in lines[0], err
    assert "pip install 'edc-bench[train]'" in lines[0] and "(scikit-learn, skl2onnx not installed)" in lines[0]
    assert out == ""


def _numeric_flags() -> list[tuple[str, str]]:
    """Every command's flag that takes a number (its type turns "2" or "1.5" into one)."""
    found = []
    commands = build_parser()._subparsers._group_actions[0].choices  # type: ignore[union-attr]
    for name, command in commands.items():
        for action in command._actions:
            if action.type is None or not action.option_strings:
                continue
            for probe in ("2", "1.5"):
                try:
                    value = action.type(probe)  # type: ignore[operator]
                except Exception:  # noqa: BLE001 - not a number this flag takes
                    continue
                if isinstance(value, (int, float)) and not isinstance(value, bool):
                    found.append((name, action.option_strings[-1]))
                    break
    return found


def test_there_are_numeric_flags_to_check() -> None:
    flags = _numeric_flags()
    assert ("web", "--port") in flags and ("test", "--seed") in flags and len(flags) > 25


@pytest.mark.parametrize("value", ["nan", "inf", "-inf", "1e400", "99999999999999999999"])
def test_no_numeric_flag_takes_a_number_no_bench_can_use(value: str, capsys: pytest.CaptureFixture[str]) -> None:
    """Refused by the parser or by the command's own check, in one line; never a traceback (exit 70)."""
    from edc_bench.cli import _run

    parser = build_parser()
    taken = []
    for command, flag in _numeric_flags():
        try:
            args = parser.parse_args([command, f"{flag}={value}"])
        except SystemExit as exc:
            assert exc.code == 2
            continue
        taken.append((command, flag, args))
    capsys.readouterr()
    # a flag the parser leaves to its command (one whose range depends on others) is checked by it before any work
    checked_by_the_command = {("train", "--marginal-band"), ("train", "--prior-weight"), ("label", "--clearance-mm"),
                              ("check-station", "--duration-s"), ("classify", "--af"), ("classify", "--a1")}
    assert {(c, f) for c, f, _ in taken} <= checked_by_the_command
    for command, flag, _ in taken:
        argv = {"label": ["label", "V-1", "worn"], "train": ["train", "--from-history"]}.get(command, [command])
        code = _cli([*argv, f"{flag}={value}"])
        _, err = capsys.readouterr()
        assert code == ExitCode.BAD_INPUT, (command, flag, err)
        assert err.count("\n") == 1 and "Traceback" not in err, err


@pytest.mark.parametrize("port", ["0", "65536", "99999", "-1", "http"])
def test_a_web_port_out_of_range_is_refused_in_one_line(port: str, capsys: pytest.CaptureFixture[str]) -> None:
    code = _cli(["web", "--port", port])
    out, err = capsys.readouterr()
    assert code == ExitCode.BAD_INPUT and out == ""
    assert "give one from 1 to 65535" in err or "give a whole number from 1 to 65535" in err, err


def test_a_web_port_in_use_is_one_line_before_any_url(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from edc_bench.history.store import HistoryStore

    url = f"sqlite:///{tmp_path}/h.sqlite"
    HistoryStore(url).close()
    with socket.create_server(("127.0.0.1", 0)) as taken:
        port = taken.getsockname()[1]
        code = _cli(["web", "--port", str(port), "--db", url, "--records", str(tmp_path)])
    out, err = capsys.readouterr()
    assert code == ExitCode.BAD_INPUT, err
    assert out == ""  # no "serving ... on http://..." for a server that never served
    assert f"--port {port}: cannot serve there" in err and "give another --port" in err


def test_a_web_certificate_that_is_none_is_one_line_before_any_url(tmp_path: Path,
                                                                   capsys: pytest.CaptureFixture[str]) -> None:
    """The review's finding: a --certfile that is no PEM printed the URL, then an ssl.SSLError traceback (exit 70)."""
    bogus = tmp_path / "cert.pem"
    bogus.write_text("not a certificate\n", encoding="utf-8")
    code = _cli(["web", "--host", "0.0.0.0", "--allow-remote", "--certfile", str(bogus), "--keyfile", str(bogus),
                 "--db", f"sqlite:///{tmp_path}/h.sqlite"])
    out, err = capsys.readouterr()
    assert code == ExitCode.BAD_INPUT and out == "", err
    assert "not a certificate and its key in PEM" in err and err.count("\n") == 1, err
