"""Figures of docs/new-pump-type.md: the walkthrough's pump, and what the commands print for it.

The walkthrough's variant file is written into a temporary station (its variant, data and cache folders), as
``tests/cli/test_new_pump_type.py`` writes it, and the commands run in this process against the simulated rig.
The pump's figures, the gain check's refusal and the "not calibrated" reason are computed while the page is
written; the walkthrough itself (tune, a test, five calibrations, a new and a worn valve) is the measurement
``new-pump-type-walkthrough``.
"""

from __future__ import annotations

import contextlib
import json
import math
import re
import textwrap
import tomllib
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from edc_bench.testing.new_pump_type import CHANGES, NAME, new_pump_type_text
from figures.common import isolated_station, measurement, percent, run_cli, stored

WIDTH = 110  # the transcripts' line length on the page
RIG = ["--interface", "socketcan", "--channel", "can0"]


def variant_text() -> str:
    """The walkthrough's variant file (:mod:`edc_bench.testing.new_pump_type`, which the tests use too)."""
    return new_pump_type_text()


@contextlib.contextmanager
def new_pump_station() -> Iterator[Path]:
    """A temporary station whose variant folder holds the walkthrough's file; yields the station's folder."""
    import os

    with isolated_station() as root:
        folder = Path(os.environ["EDC_BENCH_VARIANTS_DIR"])
        folder.mkdir(parents=True)
        (folder / f"{NAME}.toml").write_text(variant_text(), encoding="utf-8")
        yield root


def pump_sentence() -> str:
    """The walkthrough's pump in a sentence, from its file."""
    from edc_bench.config import load_variant, parse_variant

    new, default = parse_variant(tomllib.loads(variant_text())), load_variant("p-edc-default")
    ratio = new.coil.force_constant_n_per_a / default.coil.force_constant_n_per_a
    return (f"The walkthrough below uses a pump unlike the shipped ones: force constant "
            f"{new.coil.force_constant_n_per_a:g} N/A ({ratio:.1f} times `p-edc-default`'s), rack mass "
            f"{new.rack.mass_kg:g} kg, spring {new.rack.spring_n_per_mm:g} N/mm, coil {new.coil.resistance_ohm:g} ohm "
            f"and {new.coil.inductance_mh:g} mH. `tests/cli/test_new_pump_type.py` runs these commands against the "
            f"simulated rig, and the outputs and figures below are printed by running them "
            f"(`docs/figures/new_pump_type.py`), so they stay true.")


def changed_lines() -> str:
    """The walkthrough file's lines that differ from ``p-edc-default.toml``, under their tables, as a TOML block."""
    from edc_bench.config.loader import variant_file

    default = variant_file("p-edc-default").read_text(encoding="utf-8")
    tables: dict[str, list[str]] = {}
    for old, new in CHANGES.items():
        headers = re.findall(r"^\[[^\]]+\]", default[:default.index(old)], re.MULTILINE)
        tables.setdefault(headers[-1], []).append(new.strip())
    blocks = ["\n".join([header, *lines]) for header, lines in tables.items()]
    return "```toml\n" + "\n\n".join(blocks) + "\n```"


def _wrapped(text: str, indent: str = "") -> str:
    return textwrap.fill(text, WIDTH, subsequent_indent=indent, break_on_hyphens=False, break_long_words=False)


def refused_transcript() -> str:
    """``edc-bench test`` on the new pump with the default's gains: the gain check's refusal."""
    from edc_bench.config import load_variant
    from edc_bench.errors import ConfigError
    from edc_bench.runtime.gain_check import check_variant_gains

    with new_pump_station():
        try:
            check_variant_gains(load_variant(NAME))
            message = "(accepted)"
        except ConfigError as exc:
            message = f"edc-bench test: error: {exc}"
    return f"```text\n$ edc-bench test --variant {NAME}\n{_wrapped(message)}\n```"


def not_calibrated_transcript() -> str:
    """What a test on the rig says before calibration (the reason's text, with the rig's calibrate command)."""
    from edc_bench.config import load_variant
    from edc_bench.verdict.judgement import (
        default_calibrate_command,
        not_calibrated_reason,
    )

    before = stored("new-pump-type-walkthrough")["before"]
    if before["verdict"] != "INVALID":  # the walkthrough's own test before calibrating must agree with the page
        raise RuntimeError(f"the new pump's test before calibration gave {before['verdict']}, not INVALID")
    with new_pump_station():
        variant = load_variant(NAME)
        reason = not_calibrated_reason(variant, default_calibrate_command(variant, RIG))
    from edc_bench.engine.problems import Problem
    from edc_bench.records.advice import advice

    words = advice("INVALID", Problem.NOT_CALIBRATED).words  # the first line, as test_cmd prints it
    return (f"```text\n$ edc-bench test --variant {NAME} {' '.join(RIG)}\nverdict: INVALID, {words}\n"
            f"{_wrapped('  - ' + reason, '    ')}\n...\n```")


# --------------------------------------------------------------------------- the walkthrough (measured)


def _test(*args: str) -> dict[str, Any]:
    """``edc-bench test`` on the simulated rig, JSON summary plus the exit code."""
    code, out, err = run_cli(["test", "--variant", NAME, "--no-history", "--no-figure", "--json", "--out", "records",
                              *args])
    return {"code": code, **(json.loads(out) if out else {}), "stderr": err}


@measurement("new-pump-type-walkthrough", minutes=0.3)
def walkthrough() -> dict[str, Any]:
    """Steps 3-5 on the simulated rig: tune, a test before calibration, five calibrations, a new and a worn valve."""
    with new_pump_station() as root:
        code, tune_out, _ = run_cli(["tune", "--variant", NAME])
        if code != 0 or run_cli(["tune", "--variant", NAME, "--write"])[0] != 0:
            raise RuntimeError("edc-bench tune failed")
        before = _test()
        for n in range(5):
            code, _, err = run_cli(["calibrate", "--variant", NAME, "--valve", "new", "--append",
                                    "--valve-id", f"N-{n + 1:04d}", "--out", "records"])
            if code != 0:
                raise RuntimeError(f"edc-bench calibrate failed: {err}")
        baseline_file = root / "variants" / "baselines" / f"{NAME}.toml"
        baseline = tomllib.loads(baseline_file.read_text(encoding="utf-8"))
        new, worn = _test("--valve", "new"), _test("--valve", "worn")
    truth = before["truth"]
    return {
        "tune": tune_out.replace(str(root), "...").rstrip("\n"),
        "before": {"verdict": before["verdict"], "converged": before["converged"]},
        "baseline": {"tests": baseline["tests"],
                     "af_error": round(baseline["af_v"] / truth["af"] - 1, 7),
                     "a1_error": round(baseline["a1_v_s_per_mm"] / truth["a1"] - 1, 7),
                     "af_u": round(baseline["af_uncertainty_v"] / baseline["af_v"], 7),
                     "a1_u": round(baseline["a1_uncertainty_v_s_per_mm"] / baseline["a1_v_s_per_mm"], 7)},
        "valves": {name: {"verdict": r["verdict"], "af": round(r["classification"]["features_rel"]["af"], 4),
                          "a1": round(r["classification"]["features_rel"]["a1"], 4),
                          "settle_s": round(max(r["settle_s"]["af"], r["settle_s"]["a1"]), 2)}
                   for name, r in (("new", new), ("worn", worn))},
    }


def tune_transcript() -> str:
    """``edc-bench tune`` for the new pump, as it printed (the file's folder shortened to ...)."""
    lines = [line if line.startswith(("present", "proposed", " ")) else _wrapped(line)
             for line in stored("new-pump-type-walkthrough")["tune"].splitlines()]
    return f"```text\n$ edc-bench tune --variant {NAME}\n" + "\n".join(lines) + "\n```"


def off_by(value: float) -> str:
    """A relative error in words: '0.22 % below', '0.22 % above', or 'within 0.01 % of'."""
    if round(abs(value) * 100, 2) == 0:
        return "within 0.01 % of"
    return f"{percent(abs(value), 2)} {'below' if value < 0 else 'above'}"


def baseline_sentence() -> str:
    """How close five calibration runs came to the simulated plant."""
    b = stored("new-pump-type-walkthrough")["baseline"]
    count = {5: "five"}.get(b["tests"], str(b["tests"]))
    return (f"`tests/cli/test_new_pump_type.py` calibrates {count} such runs (one simulated new valve; calibrate "
            f"gives each run its own noise seed). The baseline's af came out {off_by(b['af_error'])} the simulated "
            f"plant's, its a1 {off_by(b['a1_error'])} the plant's, with a stated uncertainty of "
            f"{percent(b['af_u'], 2)} (af) and {percent(b['a1_u'], 2)} (a1).")


def verify_sentence() -> str:
    """The new and the worn valve after calibration."""
    v = stored("new-pump-type-walkthrough")["valves"]
    new, worn = v["new"], v["worn"]
    return (f"On the simulated rig (`--valve new`, `--valve worn`) the new pump type gave {new['verdict']} with af "
            f"x{new['af']:.2f}, a1 x{new['a1']:.2f}, and {worn['verdict']} with af x{worn['af']:.2f}, a1 "
            f"x{worn['a1']:.2f}. In both tests the online estimates of af and a1 settled within "
            f"{math.ceil(max(new['settle_s'], worn['settle_s']) * 10 - 1e-6) / 10:.1f} s of the move to mid-stroke "
            f"(the record's `online_settle_s`).")
