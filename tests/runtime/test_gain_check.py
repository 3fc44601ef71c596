"""The gain check's loop margins are cached on disk; a bad cache file is recomputed, not trusted."""

from __future__ import annotations

from pathlib import Path

import pytest

from edc_bench.config import Variant
from edc_bench.control.stability import loop_margins
from edc_bench.physics.valve import nominal_plant
from edc_bench.runtime.gain_check import cached_loop_margins


def test_gain_check_margins_are_cached_and_a_bad_cache_is_ignored(variant: Variant, tmp_path: Path,
                                                                  monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("EDC_BENCH_CACHE_DIR", str(tmp_path))
    c = variant.controller
    args = (nominal_plant(variant), c.kp_v_per_mm, c.ki_v_per_mm_s, c.kd_v_s_per_mm, c.derivative_filter_hz,
            c.period_s)
    computed = loop_margins(*args)
    assert cached_loop_margins(*args) == computed
    files = list((tmp_path / "loop-margins").glob("*.json"))
    assert len(files) == 1
    assert cached_loop_margins(*args) == computed  # read back
    files[0].write_text("{not json", encoding="utf-8")
    assert cached_loop_margins(*args) == computed  # recomputed, not trusted
    other = cached_loop_margins(*args[:1], c.kp_v_per_mm * 2, *args[2:])
    assert other != computed  # different gains, different entry
