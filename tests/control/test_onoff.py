"""Control with on/off valves: the PWM pulser, PWM pressure control and seed 004's
sliding-mode positioning, in closed loop with the simulated on/off muscle."""

from __future__ import annotations

import math
import random

import pytest

from pamd.control.onoff import EXHAUST, HOLD, INFLATE, PwmPressure, SlidingModePosition
from pamd.models.velocity import velocity_step
from pamd.sim.onoff import OnOffValves
from pamd.sim.options import SimMuscleOptions
from pamd.sim.plant import MusclePlant

DT = 0.001


def _states(ctrl: PwmPressure, error_bar: float, n: int) -> list[int]:
    return [ctrl.step(k * DT, DT, error_bar, 0.0, 0.0) for k in range(n)]


def test_a_duty_opens_the_valve_for_its_share_of_each_period() -> None:
    ctrl = PwmPressure(period_s=0.02, min_pulse_s=0.003, kp_per_bar=1.0, ki_per_bar_s=0.0,
                       rate_feedforward_s_per_bar=0.0)
    states = _states(ctrl, 0.25, 40)  # duty 0.25 of 20 ms: 5 ms open, then hold
    assert states[:5] == [INFLATE] * 5 and states[5:20] == [HOLD] * 15
    assert states[20:25] == [INFLATE] * 5
    ctrl.reset()
    assert _states(ctrl, -0.5, 20).count(EXHAUST) == 10


def test_a_pulse_shorter_than_the_valves_can_pass_is_not_sent() -> None:
    ctrl = PwmPressure(period_s=0.02, min_pulse_s=0.003, kp_per_bar=1.0, ki_per_bar_s=0.0,
                       rate_feedforward_s_per_bar=0.0)
    assert set(_states(ctrl, 0.1, 100)) == {HOLD}  # 2 ms < 3 ms


def _onoff_plant(**options: float) -> tuple[MusclePlant, OnOffValves]:
    plant = MusclePlant(SimMuscleOptions(actuation="onoff", **options), random.Random(0))
    assert isinstance(plant.regulator, OnOffValves)
    return plant, plant.regulator


def _apply(valves: OnOffValves, state: int) -> None:
    valves.set_inflate(state == INFLATE)
    valves.exhaust_open = state == EXHAUST


def test_pwm_pressure_control_follows_the_seeds_sine() -> None:
    """0.05 Hz, 0-6 bar, 30 kg, after the first half cycle: within the issue's
    0.1 bar RMSE."""
    plant, valves = _onoff_plant(load_kg=30.0)
    ctrl = PwmPressure(period_s=0.02, min_pulse_s=0.003, kp_per_bar=3.0, ki_per_bar_s=5.0,
                       rate_feedforward_s_per_bar=0.02)
    sq, n, t = 0.0, 0, 0.0
    for _ in range(round(30.0 / DT)):
        w = 2.0 * math.pi * 0.05
        sp, rate = 3.0 - 3.0 * math.cos(w * t), 3.0 * w * math.sin(w * t)
        _apply(valves, ctrl.step(t, DT, sp, plant.pressure_read_bar, rate))
        plant.advance(DT)
        t += DT
        if t > 10.0:
            sq += (plant.pressure_bar - sp) ** 2
            n += 1
    assert math.sqrt(sq / n) < 0.1


def test_sliding_mode_settles_a_10_mm_step_and_then_leaves_the_valves_alone() -> None:
    plant, valves = _onoff_plant(load_kg=30.0, initial_pressure_bar=3.0)
    plant.advance(1.0)
    ctrl = SlidingModePosition(lambda_per_s=10.0, boundary_mm_s=20.0, hold_band_mm=0.01,
                               period_s=0.05, min_pulse_s=0.003)
    target = plant.length_read_mm - 10.0
    v, prev, t = 0.0, math.nan, 0.0
    worst_after_2s = 0.0
    switchings_at_2s = 0
    for _ in range(round(4.0 / DT)):
        length = plant.length_read_mm
        v = velocity_step(v, prev, length, DT, 0.01)
        prev = length
        _apply(valves, ctrl.step(t, length, v, target, 0.0))
        plant.advance(DT)
        t += DT
        if t >= 2.0:
            if switchings_at_2s == 0:
                switchings_at_2s = valves.switchings
            worst_after_2s = max(worst_after_2s, abs(plant.length_read_mm - target))
    assert worst_after_2s <= 0.02 + 1e-9
    assert valves.switchings - switchings_at_2s <= 2 * 5 * 2  # <= 5/s per valve at rest
    assert plant.length_mm == pytest.approx(target, abs=0.02)
