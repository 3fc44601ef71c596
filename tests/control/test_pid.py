"""Discrete PID: components, anti-windup, limits, derivative filter."""

from __future__ import annotations

import math

import pytest

from edc_bench.control.pid import Pid, PidGains


def test_proportional_and_integral() -> None:
    pid = Pid(PidGains(2.0, 10.0, 0.0, 100.0), 1e-3, 24.0)
    assert pid.update(0.5) == pytest.approx(2.0 * 0.5 + 10.0 * 0.5e-3)
    for _ in range(999):
        pid.update(0.5)
    assert pid.integral_v == pytest.approx(10.0 * 0.5 * 1.0)


def test_derivative_is_filtered_first_order() -> None:
    kd, fc = 0.01, 100.0
    pid = Pid(PidGains(0.0, 0.0, kd, fc), 1e-3, 24.0)
    pid.update(0.0)
    first = pid.update(1.0)  # a unit step in the error
    tau = 1 / (2 * math.pi * fc)
    assert first == pytest.approx(kd / (tau + 1e-3))
    # then decays geometrically with a = tau / (tau + T)
    second = pid.update(1.0)
    assert second == pytest.approx(first * tau / (tau + 1e-3))


def test_output_limits_and_anti_windup() -> None:
    pid = Pid(PidGains(1.0, 100.0, 0.0, 100.0), 1e-3, 5.0)
    for _ in range(2000):
        u = pid.update(10.0, saturated_sign=1)  # the total drive is at its upper limit
        assert -5.0 <= u <= 5.0
    assert pid.integral_v == 0.0  # held while saturated in the same direction
    pid.update(-1.0, saturated_sign=1)  # an error pulling back out still integrates
    assert pid.integral_v < 0.0


def test_integrator_is_bounded_by_the_limit() -> None:
    pid = Pid(PidGains(0.0, 1000.0, 0.0, 100.0), 1e-3, 5.0)
    for _ in range(1000):
        pid.update(10.0)
    assert pid.integral_v == 5.0
