"""``edc-bench tune``: propose PID gains for a variant's nominal plant, and write them into its file."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from edc_bench.control.pid import PidGains


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Register the command."""
    p = sub.add_parser(
        "tune", help="propose PID gains that keep the variant's stability margins",
        description="Propose PID gains and the derivative filter for the variant's nominal plant (coil, rack and "
                    "spring from its file, with the transport delay acceptance.max_reply_age_ms allows) that keep "
                    "the margins [controller] asks for (min_gain_margin_db, min_phase_margin_deg) with the most "
                    "closed-loop bandwidth. Prints the margins, the bandwidth and the expected settling of the "
                    "present gains and the proposed ones. No gains that keep the margins is bad input (exit 2).",
    )
    p.add_argument("--variant", default=None, metavar="NAME|PART|PATH", help="pump variant (default: p-edc-default)")
    p.add_argument("--write", action="store_true",
                   help="put the proposed gains into the variant's file, keeping its comments and layout")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    """Tune, print, and write if asked."""
    from edc_bench.config import load_variant
    from edc_bench.config.loader import variant_file
    from edc_bench.control.pid import PidGains
    from edc_bench.control.stability import loop_margins
    from edc_bench.control.tuning import step_figures, tune_pid
    from edc_bench.physics.valve import nominal_plant
    from edc_bench.engine.replies import max_reply_age_ticks

    variant = load_variant(args.variant)
    path = variant_file(args.variant)
    if args.write:
        from edc_bench.cli.common import probe_writable
        from edc_bench.config.loader import is_shipped
        from edc_bench.errors import ConfigError

        if is_shipped(path):  # its baselines and models were made with its gains: never changed in place
            raise ConfigError(f"--write: {path} is a shipped variant and is not changed in place; copy it to the "
                              f"station's variants folder under a new [pump].name (docs/new-pump-type.md) and tune "
                              "that file")

        # the gains are written by replacing the file: its folder must take a new file, checked before tuning
        probe_writable(path.parent, f"--write: the folder of {path} is not writable; copy the variant to a "
                                    "writable place and tune that file")
    c = variant.controller
    plant = nominal_plant(variant)
    delay_ticks = max_reply_age_ticks(variant)
    print(f"variant {variant.name} ({path}): nominal plant with {delay_ticks} ticks of transport delay "
          f"(acceptance.max_reply_age_ms = {variant.acceptance.max_reply_age_ms:g} at a "
          f"{c.period_s * 1e3:g} ms tick); margins asked for: {c.min_gain_margin_db:g} dB, "
          f"{c.min_phase_margin_deg:g} deg")
    present = PidGains(c.kp_v_per_mm, c.ki_v_per_mm_s, c.kd_v_s_per_mm, c.derivative_filter_hz)
    margins = loop_margins(plant, *_values(present), c.period_s, delay_ticks)
    rows = [("present", present, margins, *(step_figures(plant, present, c.period_s, delay_ticks)
                                            if margins.closed_loop_stable else (float("nan"),) * 3))]
    tuned = tune_pid(plant, c.period_s, delay_ticks, c.min_gain_margin_db, c.min_phase_margin_deg)
    rows.append(("proposed", tuned.gains, tuned.margins, tuned.closed_loop_bandwidth_hz, tuned.settling_s,
                 tuned.overshoot_pct))
    print(f"{'':<9} {'kp V/mm':>8} {'ki V/mm/s':>10} {'kd V s/mm':>10} {'filter Hz':>9} {'GM dB':>6} "
          f"{'PM deg':>6} {'crossover Hz':>12} {'bandwidth Hz':>12} {'settling s':>10} {'overshoot':>9}")
    for label, gains, m, bandwidth_hz, settling_s, overshoot in rows:
        stable = "" if m.closed_loop_stable else "  UNSTABLE"
        print(f"{label:<9} {gains.kp_v_per_mm:>8.4g} {gains.ki_v_per_mm_s:>10.4g} {gains.kd_v_s_per_mm:>10.4g} "
              f"{gains.derivative_filter_hz:>9.4g} {m.gain_margin_db:>6.1f} {m.phase_margin_deg:>6.1f} "
              f"{m.crossover_hz:>12.1f} {bandwidth_hz:>12.1f} {settling_s:>10.3f} {overshoot:>8.1f}%{stable}")
    print("bandwidth: where the reference-to-rack response falls 3 dB; settling: a reference step to within 2 %, "
          "feedback alone (the feedforward does most of the work once it has learnt)")
    if not args.write:
        print(f"to use them: edc-bench tune --variant {args.variant or variant.name} --write")
        return 0
    _write_gains(path, tuned.gains)
    load_variant(path)  # the file as written must still be a valid variant
    print(f"gains written to [controller] of {path}", file=sys.stderr)
    return 0


def _values(gains: PidGains) -> tuple[float, float, float, float]:
    return gains.kp_v_per_mm, gains.ki_v_per_mm_s, gains.kd_v_s_per_mm, gains.derivative_filter_hz


def _write_gains(file: Path, gains: PidGains) -> None:
    """Replace the gains in the file's [controller] table, keeping every comment and the layout."""
    import contextlib

    import tomlkit

    from edc_bench.errors import ConfigError

    temporary = file.with_name(f".{file.name}.tune")
    try:
        document = tomlkit.parse(file.read_text(encoding="utf-8"))
        table = document["controller"]
        for key, value in zip(("kp_v_per_mm", "ki_v_per_mm_s", "kd_v_s_per_mm", "derivative_filter_hz"),
                              _values(gains), strict=True):
            table[key] = value
        text = tomlkit.dumps(document)
        temporary.write_text(text, encoding="utf-8")
        temporary.replace(file)  # a crash never leaves half a variant file
    except OSError as exc:
        from edc_bench.errors import RecordNotWrittenError, disk_full

        if temporary.is_file():  # what a full disk let through is no variant file
            with contextlib.suppress(OSError):
                temporary.unlink()
        error = RecordNotWrittenError if disk_full(exc) else ConfigError  # a full disk is exit 74, as everywhere
        raise error(f"{file}: cannot write the gains ({exc.strerror}); copy the proposed gains into its "
                    "[controller] table by hand") from None
