"""Simulated sensors: sample period, latency, noise, filter and quantisation."""

from __future__ import annotations

import math
import random
from collections.abc import Callable
from typing import Any

import pytest

from pamd.sim.options import SimMuscleOptions
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


def test_the_driver_publishes_a_bursty_links_arrival_stamps_and_their_jitter(
        make_rig: Callable[..., Any]) -> None:
    rig = make_rig(SimMuscleOptions(length_burst_s=0.04, burst_every_s=0.5,
                                    force_adc_bits=16, force_noise_n=0.0))
    li, fi = rig.driver.input_index("m1.length"), rig.driver.input_index("m1.force")
    seen = []
    for _ in range(700):
        rig.step(0.001)
        seen.append((rig.t_s, rig.driver.in_stamps_s[li], rig.driver.in_jitter_s[li],
                     rig.driver.in_values[fi]))
    # held 0.50 .. 0.54 s: the stamp stands still, then arrivals carry the hold as jitter
    held = {st for t, st, _, _ in seen if 0.501 <= t < 0.54}
    assert len(held) == 1
    assert max(j for t, _, j, _ in seen if 0.54 <= t < 0.56) >= 0.039
    assert max(j for t, _, j, _ in seen if 0.2 <= t < 0.5) <= 0.001 + 1e-9
    assert rig.driver.in_jitter_s[fi] == 0.0  # the load cell says when it sampled
    # a 16-bit noiseless load cell under a dead weight at rest: one constant value
    assert len({f for t, _, _, f in seen if t > 0.3}) == 1
