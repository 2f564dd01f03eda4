"""Identification from measured responses and the gains derived from it, on plants
with a known delay and lag (the analytic gains are known too)."""

from __future__ import annotations

import math
import random

import numpy as np
import pytest

from pamd.loop.control.tuning import (
    Fopdt,
    IdentificationError,
    fit_step,
    rate_feedforward_s,
    relay_fopdt,
    relay_oscillation,
    simc_pi,
)

DT = 0.001


class FopdtPlant:
    """A sampled FOPDT plant: y follows u delayed by theta through a lag tau."""

    def __init__(self, gain: float, tau_s: float, theta_s: float, noise: float = 0.0,
                 seed: int = 0) -> None:
        self.gain, self.tau, self.delay = gain, tau_s, round(theta_s / DT)
        self.queue = [0.0] * self.delay
        self.x = 0.0
        self.noise = noise
        self.rng = random.Random(seed)

    def step(self, u: float) -> float:
        self.queue.append(u)
        delayed = self.queue.pop(0)
        self.x += (self.gain * delayed - self.x) * (1.0 - math.exp(-DT / self.tau))
        return self.x + self.rng.gauss(0.0, self.noise)


@pytest.mark.parametrize(("gain", "tau", "theta"), [(1.0, 0.025, 0.010), (0.8, 0.060, 0.020),
                                                    (2.0, 0.5, 0.1)])
def test_a_step_response_gives_back_the_plant(gain, tau, theta) -> None:
    plant = FopdtPlant(gain, tau, theta, noise=0.003)
    n = round((0.2 + 10 * (tau + theta)) / DT)
    t = np.arange(n) * DT
    y = np.array([plant.step(1.5 if tk >= 0.2 else 0.0) for tk in t])
    model = fit_step(t, y, 0.2, 1.5)
    assert model.gain == pytest.approx(gain, rel=0.02)
    assert model.tau_s == pytest.approx(tau, rel=0.1)
    assert model.dead_time_s == pytest.approx(theta, abs=0.002 + 0.05 * theta)


def test_simc_gains_are_within_20_percent_of_the_analytic_ones() -> None:
    """The identified model's SIMC gains against those of the true plant."""
    true = Fopdt(1.0, 0.030, 0.010)
    plant = FopdtPlant(true.gain, true.tau_s, true.dead_time_s, noise=0.003)
    t = np.arange(round(0.6 / DT)) * DT
    y = np.array([plant.step(2.0 if tk >= 0.1 else 0.0) for tk in t])
    got, want = simc_pi(fit_step(t, y, 0.1, 2.0)), simc_pi(true)
    assert got.kp == pytest.approx(want.kp, rel=0.2)
    assert got.ki_per_s == pytest.approx(want.ki_per_s, rel=0.2)
    assert rate_feedforward_s(true) == pytest.approx(0.040)


def test_a_relay_test_gives_back_the_plant() -> None:
    true = Fopdt(1.0, 0.040, 0.012)
    plant = FopdtPlant(true.gain, true.tau_s, true.dead_time_s, noise=0.002)
    d, u, y, ys = 0.5, 0.5, 0.0, []
    for _ in range(round(2.0 / DT)):
        u = d if y < 0.0 else -d  # a relay around 0
        y = plant.step(u)
        ys.append(y)
    t = np.arange(len(ys)) * DT
    relay = relay_oscillation(t, np.array(ys), d)
    model = relay_fopdt(relay, true.gain)
    assert model.tau_s == pytest.approx(true.tau_s, rel=0.2)
    assert model.dead_time_s == pytest.approx(true.dead_time_s, rel=0.2)


def test_a_step_lost_in_the_noise_is_refused() -> None:
    plant = FopdtPlant(1.0, 0.03, 0.01, noise=0.05)
    t = np.arange(500) * DT
    y = np.array([plant.step(0.01 if tk >= 0.1 else 0.0) for tk in t])
    with pytest.raises(IdentificationError, match="larger step"):
        fit_step(t, y, 0.1, 0.01)


def test_a_relay_that_did_not_oscillate_is_refused() -> None:
    t = np.arange(200) * DT
    with pytest.raises(IdentificationError, match="cycles"):
        relay_oscillation(t, np.linspace(0.0, 1.0, t.size), 1.0)
