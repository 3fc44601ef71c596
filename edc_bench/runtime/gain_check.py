"""The gain check before a test, with its margins remembered on disk.

The margins themselves are pure control (:mod:`edc_bench.control.stability`);
importing python-control costs more than a second, and a technician runs the
same variant all day, so the margins of the same gains on the same plant
(and the same edc-bench and python-control versions) are computed once and
read back afterwards. An unreadable or unwritable cache only costs the
computation.
"""

from __future__ import annotations

import contextlib
import dataclasses
import hashlib
import json

from edc_bench import __version__
from edc_bench.config.loader import variant_argument
from edc_bench.config.models import Variant
from edc_bench.control.stability import LoopMargins, loop_margins, refuse_poor_margins
from edc_bench.paths import cache_dir, write_json_atomic
from edc_bench.physics.parameters import PlantParameters
from edc_bench.physics.valve import nominal_plant
from edc_bench.engine.replies import max_reply_age_ticks


def cached_loop_margins(params: PlantParameters, kp: float, ki: float, kd: float, derivative_filter_hz: float,
                        period_s: float, delay_ticks: int = 1) -> LoopMargins:
    """:func:`~edc_bench.control.stability.loop_margins`, remembered on disk for the same inputs."""
    from importlib.metadata import version

    key_data = [dataclasses.astuple(params), kp, ki, kd, derivative_filter_hz, period_s, delay_ticks,
                __version__, version("control")]
    key = hashlib.sha256(json.dumps(key_data).encode()).hexdigest()
    path = cache_dir() / "loop-margins" / f"{key}.json"
    try:
        return LoopMargins(**json.loads(path.read_text(encoding="utf-8")))
    except (OSError, ValueError, TypeError):
        pass
    margins = loop_margins(params, kp, ki, kd, derivative_filter_hz, period_s, delay_ticks)
    with contextlib.suppress(OSError):
        write_json_atomic(path, dataclasses.asdict(margins))
    return margins


def check_variant_gains(variant: Variant) -> LoopMargins:
    """Margins of the variant's gains on its nominal plant; refuses unstable or marginal gains.

    Raises
    ------
    ConfigError
        Naming the margins found and the minimums the variant asks for.
    """
    c = variant.controller
    margins = cached_loop_margins(nominal_plant(variant), c.kp_v_per_mm, c.ki_v_per_mm_s, c.kd_v_s_per_mm,
                                  c.derivative_filter_hz, c.period_s, max_reply_age_ticks(variant))
    return refuse_poor_margins(variant, margins, variant_argument(variant))
