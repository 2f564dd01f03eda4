"""PID: terms, anti-windup, filtered derivative on measurement, bumpless reset."""

from __future__ import annotations

import pytest

from pamd.loop.control.pid import Pid


def test_proportional_and_integral_terms() -> None:
    pid = Pid(kp=2.0, ki_per_s=10.0, kd_s=0.0, derivative_filter_hz=50.0,
              integral_limit=10.0, output_limit=100.0)
    pid.reset(0.0)
    u = pid.step(error=1.0, measured=0.0, dt_s=0.001)
    assert pid.p == pytest.approx(2.0)
    assert pid.i == pytest.approx(0.01)
    assert u == pytest.approx(2.01)


def test_integral_clamped_and_frozen_while_saturated() -> None:
    pid = Pid(kp=0.0, ki_per_s=100.0, kd_s=0.0, derivative_filter_hz=50.0,
              integral_limit=0.5, output_limit=0.2)
    pid.reset(0.0)
    for _ in range(1000):
        u = pid.step(1.0, 0.0, 0.001)
    assert u == pytest.approx(0.2) and pid.saturated
    # Frozen at the output limit (conditional integration), not at the integral limit.
    assert pid.i <= 0.2 + 0.1 + 1e-9
    # Recovers at once when the error reverses (no wind-up to unwind).
    u = pid.step(-1.0, 0.0, 0.001)
    assert u < 0.2


def test_derivative_acts_on_measurement_not_setpoint() -> None:
    pid = Pid(kp=0.0, ki_per_s=0.0, kd_s=1.0, derivative_filter_hz=1000.0,
              integral_limit=1.0, output_limit=100.0)
    pid.reset(1.0)
    # A setpoint step (error jumps) with a steady measurement: no derivative kick.
    assert pid.step(5.0, 1.0, 0.001) == pytest.approx(0.0)
    # A rising measurement gives a negative derivative term.
    pid.step(5.0, 1.1, 0.001)
    assert pid.d < 0.0


def test_reset_is_bumpless() -> None:
    pid = Pid(kp=1.0, ki_per_s=1.0, kd_s=1.0, derivative_filter_hz=30.0,
              integral_limit=1.0, output_limit=10.0)
    pid.reset(3.0, integral=0.25)
    u = pid.step(0.0, 3.0, 0.001)
    assert u == pytest.approx(0.25)
