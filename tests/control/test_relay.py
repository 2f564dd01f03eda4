"""The relay element of the pressure stage (`pamd tune --method relay`): it makes a
plant of known delay and lag oscillate so that its model (and SIMC gains) come back
within 20 %, ends by itself, stops when no oscillation establishes, and gives way
when the setpoint moves."""

from __future__ import annotations

import numpy as np
import pytest

from pamd.config.control_schema import PidConfig
from pamd.loop.control.pressure_loop import PressureLoop
from pamd.loop.control.relay import DONE, Relay
from pamd.loop.control.tuning import Fopdt, relay_fopdt, relay_oscillation, simc_pi

from .test_tuning import DT, FopdtPlant


def _run(relay: Relay, plant: FopdtPlant, seconds: float,
         y: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    ys, us = [], []
    for _ in range(round(seconds / DT)):
        if not relay.active:
            break
        u = relay.step(y, DT)
        y = plant.step(u)
        us.append(u)
        ys.append(y)
    return np.array(us), np.array(ys)


def test_the_relay_gives_back_a_plant_with_known_delay_and_lag() -> None:
    true = Fopdt(0.95, 0.013, 0.0125)  # the shape of the regulator's step fit
    plant = FopdtPlant(true.gain, true.tau_s, true.dead_time_s, noise=0.002)
    for _ in range(round(0.5 / DT)):  # rest at the level: 3 bar in, 2.85 out
        y = plant.step(3.0)
    relay = Relay()
    relay.start(3.0, 0.2, 0.02, cycles=8, timeout_s=1.0)
    us, ys = _run(relay, plant, 5.0, y)
    assert relay.outcome == DONE and relay.switches == 16
    assert relay.switch_bar == pytest.approx(2.85, abs=0.005)
    assert set(np.round(us[round(relay.relay_start_s / DT):-1], 6)) == {2.8, 3.2}
    assert us[-1] == 3.0  # done: back to the center
    t = np.arange(ys.size) * DT
    sel = t >= relay.relay_start_s
    osc = relay_oscillation(t[sel], ys[sel], 0.2)
    model = relay_fopdt(osc, relay.switch_bar / 3.0, 0.02)
    got, want = simc_pi(model), simc_pi(true)
    assert model.dead_time_s == pytest.approx(true.dead_time_s, rel=0.2)
    assert model.tau_s == pytest.approx(true.tau_s, rel=0.2)
    assert got.kp == pytest.approx(want.kp, rel=0.2)
    assert got.ki_per_s == pytest.approx(want.ki_per_s, rel=0.2)


def test_no_oscillation_stops_it_with_the_reason() -> None:
    plant = FopdtPlant(0.0, 0.01, 0.01, noise=0.0)  # a regulator that does not respond
    relay = Relay()
    relay.start(3.0, 0.2, 0.02, cycles=8, timeout_s=0.5)
    us, _ = _run(relay, plant, 5.0)
    assert not relay.active
    assert relay.outcome.startswith("the oscillation did not establish")
    assert "within 0.5 s" in relay.outcome
    assert us.size < round(1.0 / DT)  # settle + timeout, not the 5 s
    assert us[-1] == 3.0  # ends at the center


def test_a_moved_setpoint_or_an_opened_loop_ends_it() -> None:
    loop = PressureLoop(PidConfig(kp=0.5, ki_per_s=40.0), 0.025)
    loop.relay.start(3.0, 0.2, 0.02, cycles=8, timeout_s=1.0)
    loop.step(2.5, 5.0, 2.4, True, True, DT)  # still ramping to the center: it waits
    assert loop.relay.active and loop.relay.elapsed_s == 0.0
    assert loop.step(3.0, 0.0, 2.9, True, True, DT) == 3.0  # settling: the center
    loop.step(3.1, 0.0, 2.9, True, True, DT)
    assert not loop.relay.active and "setpoint moved" in loop.relay.outcome
    loop.relay.start(3.0, 0.2, 0.02, cycles=8, timeout_s=1.0)
    assert loop.step(3.0, 0.0, 2.9, False, False, DT) == 3.0
    assert not loop.relay.active and "loop opened" in loop.relay.outcome
