"""What a person reads when something is off: a truncated log names its line, a figure not identified is not
"nan", a folder indexed twice is counted once."""

from __future__ import annotations

from pathlib import Path

import pytest

from edc_bench.cli import main
from edc_bench.cli.test_cmd import _value_and_spread


@pytest.fixture(scope="module")
def record(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("rec")
    assert main(["test", "--out", str(out), "--no-history", "--no-figure", "--json"]) == 0
    return next(out.iterdir())


def test_a_truncated_can_log_names_its_last_line(record: Path, tmp_path: Path,
                                                 capsys: pytest.CaptureFixture[str]) -> None:
    cut = tmp_path / "cut.log"
    cut.write_bytes((record / "can.log").read_bytes()[:3000])
    assert main(["replay", str(record), "--can-log", str(cut)]) == 2
    err = capsys.readouterr().err
    assert "truncated" in err and f"{cut}: line " in err and "Traceback" not in err and "ValueError" not in err


def test_a_figure_not_identified_is_not_nan() -> None:
    assert _value_and_spread(float("nan"), float("nan")) == "not identified"
    assert "nan" not in _value_and_spread(0.07, float("nan"))
    assert _value_and_spread(0.0696, 0.0004) == "0.0696 +/- 0.0004"


def test_a_folder_given_twice_is_indexed_once(record: Path, tmp_path: Path,
                                              capsys: pytest.CaptureFixture[str]) -> None:
    db = f"sqlite:///{tmp_path / 'h.sqlite'}"
    assert main(["history", "--db", db, "--add", str(record), str(record)]) == 0
    assert "indexed 1 new record folder(s)" in capsys.readouterr().err
    assert main(["history", "--db", db, "--add", str(record)]) == 0
    assert "indexed 0 new record folder(s)" in capsys.readouterr().err


def test_a_model_fit_over_one_period_prints_no_nan() -> None:
    # one whole period (a test interrupted early): nothing the same every period, no spread between periods
    import math

    from edc_bench.identification.analysis import ModelFit, model_fit_line

    one_period = ModelFit(1e-3, 1e-3, 1.95, {"af": math.nan, "a1": math.nan}, 0.0, [], systematic_ratio=math.nan)
    assert model_fit_line(one_period) == ("residual 1.95x the sensor noise, no period-to-period spread (one period), "
                                          "solenoid gain variation +/-0%")
    three = ModelFit(1e-3, 1e-3, 1.95, {"af": 0.002, "a1": 0.0021}, 0.05, [], systematic_ratio=0.29)
    assert model_fit_line(three, ratio_decimals=1) == (
        "residual 1.9x the sensor noise (0.3x the same every period), period-to-period spread af 0.2% a1 0.2%, "
        "solenoid gain variation +/-5%")
