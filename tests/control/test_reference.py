"""Reference: exact derivatives, soft start, and the single-sine identity."""

from __future__ import annotations

import math

import numpy as np
import pytest

from edc_bench.control.reference import Reference, Tone, smoothstep7


@pytest.fixture()
def ref() -> Reference:
    return Reference(0.3, 10.0, (Tone(0.5, 4.0), Tone(3.0, 0.5, 0.7)), move_s=1.0, fade_s=1.0)


@pytest.mark.parametrize("t", [0.2, 0.7, 1.0005, 1.3, 1.99, 2.5, 7.123])  # off the C3 joints, where r'''' jumps
def test_derivatives_match_finite_differences(ref: Reference, t: float) -> None:
    h = 1e-5
    for order in range(3):
        plus, minus = ref.at(t + h)[order], ref.at(t - h)[order]
        numeric = (plus - minus) / (2 * h)
        assert ref.at(t)[order + 1] == pytest.approx(numeric, rel=1e-5, abs=1e-4)


def test_soft_start_does_not_jump(ref: Reference) -> None:
    assert ref.at(0.0) == (0.3, 0.0, 0.0, 0.0)
    # all of r..r''' continuous across the end of the move and of the fade
    for t in (1.0, 2.0):
        before, after = np.array(ref.at(t - 1e-9)), np.array(ref.at(t + 1e-9))
        assert np.allclose(before, after, atol=1e-4)


def test_move_reaches_mid_stroke(ref: Reference) -> None:
    assert ref.at(1.0)[0] == pytest.approx(10.0)


def test_single_sine_makes_a3_and_a1_collinear() -> None:
    # docs/method.md section 10 d: r''' = -w^2 r' once the excitation is steady
    w = 2 * math.pi * 0.5
    single = Reference(10.0, 10.0, (Tone(0.5, 4.0),), move_s=1.0, fade_s=1.0)
    for t in np.linspace(2.1, 9.0, 25):
        r, r1, r2, r3 = single.at(float(t))
        assert r3 == pytest.approx(-w * w * r1, abs=1e-9)
        assert r2 == pytest.approx(-w * w * (r - 10.0), abs=1e-9)


def test_smoothstep_ends() -> None:
    assert smoothstep7(0.0) == (0.0, 0.0, 0.0, 0.0)
    assert smoothstep7(1.0) == (1.0, 0.0, 0.0, 0.0)
    assert smoothstep7(0.5)[0] == pytest.approx(0.5)


def test_peak_velocity_bounds_the_excitation(ref: Reference) -> None:
    peak = max(abs(ref.at(t)[1]) for t in np.linspace(2.0, 10.0, 4001))
    assert peak <= ref.peak_velocity_mm_s + 1e-9
