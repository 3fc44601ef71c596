"""The figures of docs/variants.md: the shipped variants, their gains' margins, and the loader's messages.

Everything here is live: the variant files in configs/ (``edc_bench.config.load_variant``), the gain check's
margins on each variant's nominal plant (``edc_bench.control.stability.loop_margins``), and the messages
``load_variant`` prints for a bad file, made by loading one.
"""

from __future__ import annotations

import tempfile
from pathlib import Path
from typing import Any

from figures.common import table

#: Mistakes shown as examples: (text in configs/p-edc-default.toml, what the mistaken file says instead).
MISTAKES = (
    ("stroke_mm = 20.0", "stroke_mm = -3.0"),
    ("stroke_mm = 20.0", "stroke_mm = 20.0\nstrok_mm = 20.0"),
    ("mass_kg = 0.30", "mass_kg = 1e308"),
)
#: The page's example of gains for a slower link (a 5 ms round trip): delay in ticks, kp, ki, kd.
SLOW_LINK = {"delay_ticks": 7, "kp_v_per_mm": 0.2, "ki_v_per_mm_s": 8.0, "kd_v_s_per_mm": 0.001}


def shipped_variants() -> dict[str, Any]:
    """The variants shipped in configs/, loaded, by name."""
    from edc_bench.config import available_variants, load_variant
    from edc_bench.config.loader import is_shipped

    return {name: load_variant(path) for name, path in available_variants().items() if is_shipped(path)}


def margins(variant: Any, *, delay_ticks: int | None = None, **gains: float) -> Any:
    """The gain check's margins of ``variant`` (its own gains and delay unless given) on its nominal plant."""
    from edc_bench.control.stability import loop_margins
    from edc_bench.engine.replies import max_reply_age_ticks
    from edc_bench.physics.valve import nominal_plant

    c = variant.controller
    kp = gains.get("kp_v_per_mm", c.kp_v_per_mm)
    ki = gains.get("ki_v_per_mm_s", c.ki_v_per_mm_s)
    kd = gains.get("kd_v_s_per_mm", c.kd_v_s_per_mm)
    ticks = max_reply_age_ticks(variant) if delay_ticks is None else delay_ticks
    return loop_margins(nominal_plant(variant), kp, ki, kd, c.derivative_filter_hz, c.period_s, ticks)


def _margin_text(m: Any) -> str:
    return f"{m.gain_margin_db:.1f} dB / {m.phase_margin_deg:.0f} deg"


def library_table() -> str:
    """The shipped variants as ``edc-bench variants`` lists them, with their rack stroke and coil (live)."""
    rows = [(f"`{name}`", f"`{v.pump.part_number}`", v.pump.description, f"{v.rack.stroke_mm:g} mm",
             f"{v.coil.resistance_ohm:g} ohm, {v.coil.inductance_mh:g} mH")
            for name, v in shipped_variants().items()]
    return table(("variant", "part number", "description", "rack stroke", "coil at 20 degC"), rows)


def gains_table() -> str:
    """The shipped variants' gains, the reply age they are checked for, and the margins the gain check finds."""
    from edc_bench.engine.replies import max_reply_age_ticks

    rows = []
    for name, v in shipped_variants().items():
        c = v.controller
        rows.append((f"`{name}`", f"{v.acceptance.max_reply_age_ms:g} ms ({max_reply_age_ticks(v)} ticks)",
                     f"{c.kp_v_per_mm:g} / {c.ki_v_per_mm_s:g} / {c.kd_v_s_per_mm:g}", _margin_text(margins(v)),
                     f"{c.min_gain_margin_db:g} dB / {c.min_phase_margin_deg:g} deg"))
    return table(("variant", "`max_reply_age_ms`", "kp / ki / kd", "margins at that delay", "asked for"), rows)


def slow_link_sentence() -> str:
    """The margins of the page's example gains for a slower link, on the default variant's nominal plant."""
    from edc_bench.config import load_variant

    s = SLOW_LINK
    m = margins(load_variant("p-edc-default"), **s)
    return (f"A slower link (a 5 ms round trip) needs `max_reply_age_ms = {s['delay_ticks']}` and gains for "
            f"{s['delay_ticks']} ticks: on `p-edc-default`'s plant, kp {s['kp_v_per_mm']:g}, ki "
            f"{s['ki_v_per_mm_s']:g}, kd {s['kd_v_s_per_mm']:g} hold {_margin_text(m)}.")


def usb_reply_age_text() -> str:
    """'2 or 3 ticks': the replies' age through the simulated usb-fs adapter (docs/simulation.md's measurement)."""
    from figures.common import stored

    ages = stored("simulation-default-test")["usb_fs"]["reply_age_ticks"]
    return " or ".join(sorted(ages, key=int))


def gains_paragraph() -> str:
    """The paragraph on the default reply age and what a USB adapter needs (reply ages measured in simulation)."""
    from edc_bench.config import load_variant

    default = load_variant("p-edc-default")
    paper = load_variant("paper")
    age = usb_reply_age_text()
    return (f"The default, {default.acceptance.max_reply_age_ms:g} ms, covers a USB full-speed CAN adapter "
            f"(CANable/slcan, gs_usb, USB PCAN and Kvaser): through the simulated one (`--adapter usb-fs`, "
            f"docs/simulation.md) replies are used {age} ticks after their command. The shipped variants' gains "
            f"are checked for the delay their file sets (the table above). A bench whose adapter answers within "
            f"{paper.acceptance.max_reply_age_ms:g} ms (PCI, socketcan on a native controller) may set "
            f"`max_reply_age_ms = {paper.acceptance.max_reply_age_ms:g}` and use faster gains; the `paper` variant "
            f"does, and therefore does not run through a USB adapter: its replies come {age.replace(' or ', '-')} "
            "ticks old and the test ends INVALID saying that replies were older than `max_reply_age_ms`.")


def load_error(content: str | bytes, name: str = "x.toml") -> str:
    """What ``load_variant`` says about a file ``configs/<name>`` holding ``content`` (the folder left out)."""
    from edc_bench.config import load_variant
    from edc_bench.errors import ConfigError

    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "configs" / name
        path.parent.mkdir()
        if isinstance(content, bytes):
            path.write_bytes(content)
        else:
            path.write_text(content, encoding="utf-8")
        try:
            load_variant(path)
        except ConfigError as error:
            return str(error).replace(f"{folder}/", "")
    raise AssertionError(f"configs/{name} was accepted")


def mistaken_default(old: str, new: str) -> str:
    """configs/p-edc-default.toml with ``old`` replaced by ``new`` (once)."""
    from edc_bench.config.loader import variant_file

    reference = variant_file("p-edc-default").read_text(encoding="utf-8")
    if old not in reference:
        raise AssertionError(f"{old!r} is not in p-edc-default.toml")
    return reference.replace(old, new, 1)


def error_examples() -> str:
    """What ``load_variant`` says about :data:`MISTAKES` in a copy of the default variant, as a fenced code block
    (cog strips a block's common indentation, so an indented block would not survive)."""
    return "\n".join(["```text", *(load_error(mistaken_default(old, new)) for old, new in MISTAKES), "```"])
