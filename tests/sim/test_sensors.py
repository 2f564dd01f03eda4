"""Simulated sensors: sample period, latency, noise, filter and quantisation."""

from __future__ import annotations

import math
import random

import pytest

from pamd.sim.sensors import SampledSensor

DT = 0.001


def run(sensor: SampledSensor, signal, seconds: float) -> list[tuple[float, float, float]]:
    """(t, value, sampled_at) after each 1 ms plant step."""
    out = []
    for k in range(1, round(seconds / DT) + 1):
        t = k * DT
        sensor.update(t, signal(t))
        out.append((t, sensor.value, sensor.sampled_at_s))
    return out


def test_a_slow_module_delivers_ten_samples_a_second_with_their_age() -> None:
    s = SampledSensor(period_s=0.1, latency_s=0.02)
    trace = run(s, lambda t: t, 1.0)
    stamps = sorted({round(at, 6) for _, _, at in trace if at > -math.inf})
    assert len(stamps) == 10
    gaps = [b - a for a, b in zip(stamps, stamps[1:], strict=False)]
    assert all(g == pytest.approx(0.1, abs=1.5e-3) for g in gaps)
    ages = [t - at for t, _, at in trace if at > -math.inf]
    assert min(ages) == pytest.approx(0.02, abs=1e-9)  # never fresher than its latency
    assert max(ages) == pytest.approx(0.12, abs=1.5e-3)  # latency + one period at worst
    # The value is the signal at the time the sample was taken, not at delivery.
    assert all(v == pytest.approx(at) for _, v, at in trace if at > -math.inf)


def test_a_fast_card_is_never_older_than_its_latency_plus_a_step() -> None:
    s = SampledSensor(period_s=0.0, latency_s=0.002)
    ages = [t - at for t, _, at in run(s, math.sin, 0.2)[5:]]
    assert max(ages) <= 0.002 + 1e-9


def test_readings_are_quantised_after_the_noise() -> None:
    s = SampledSensor(resolution=0.01, noise_sd=0.003, gauss=random.Random(1).gauss)
    values = [v for _, v, _ in run(s, lambda t: 100.0, 0.5)]
    assert all(abs(v / 0.01 - round(v / 0.01)) < 1e-6 for v in values)
    assert len(set(values)) > 1  # the noise moves it across quanta


def test_the_filter_smooths_a_step_with_its_time_constant() -> None:
    s = SampledSensor(filter_tau_s=0.05)
    trace = run(s, lambda t: 0.0 if t < 0.1 else 1.0, 0.3)
    at_tau = next(v for t, v, _ in trace if t >= 0.15 - 1e-9)
    assert at_tau == pytest.approx(1.0 - math.exp(-1.0), abs=0.02)
