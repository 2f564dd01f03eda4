"""The simulated VPPM regulator and exhaust valve, seen through the pressure sensor: the
'lag' pneumatics (the old simple plant, a filter on the setpoint) in detail, and what
the default 'flow' regulator must do the same way (dead time, backlash, clamps, zero
point, supply loss, holding at power-up)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import pytest

BOTH = pytest.mark.parametrize("pneumatics", ["lag", "flow"])


@pytest.fixture
def make_rig(make_rig: Callable[..., Any]) -> Callable[..., Any]:
    """The session's `make_rig` with the 'lag' pneumatics unless a test says otherwise."""
    def make(*muscles: Any, **kw: Any) -> Any:
        if not muscles:
            kw.setdefault("pneumatics", "lag")
        return make_rig(*muscles, **kw)
    return make


def _t63_s(make_rig, dt_s: float, **kw) -> tuple[float, float]:
    """Step 0 -> 3 bar at t = 0; (t63, final pressure) from the pressure readings."""
    rig = make_rig(**kw)
    rig.valve(3.0)
    samples = rig.run(0.6, dt_s)
    k = rig.driver.input_index("m1.pressure")
    tail = [v[k] for t, v in samples if t > 0.5]
    final = sum(tail) / len(tail)
    t63 = next(t for t, v in samples if v[k] >= 0.632 * final)
    return t63, final


@pytest.mark.parametrize(
    ("dead_s", "lag_s", "dt_s"),
    [(0.010, 0.030, 0.001), (0.010, 0.030, 0.002), (0.020, 0.050, 0.001)],
)
def test_step_t63_is_dead_time_plus_lag(make_rig, dead_s, lag_s, dt_s) -> None:
    t63, final = _t63_s(make_rig, dt_s, regulator_dead_time_s=dead_s, regulator_lag_s=lag_s)
    assert final == pytest.approx(3.0, abs=0.02)
    assert t63 == pytest.approx(dead_s + lag_s, rel=0.10)


def test_default_t63_is_about_40ms(make_rig) -> None:
    t63, _ = _t63_s(make_rig, 0.001)
    assert t63 == pytest.approx(0.040, rel=0.10)


@BOTH
def test_nothing_moves_within_the_dead_time(make_rig, pneumatics: str) -> None:
    rig = make_rig(regulator_dead_time_s=0.02, pneumatics=pneumatics)
    rig.valve(3.0)
    rig.run(0.02)
    assert abs(rig.plant.pressure_bar) < 1e-9
    rig.run(0.01)
    assert rig.plant.pressure_bar > 0.5


@BOTH
def test_backlash_swallows_small_reversals(make_rig, pneumatics: str) -> None:
    width = 0.02
    rig = make_rig(regulator_backlash_bar=width, initial_pressure_bar=0.0,
                   pneumatics=pneumatics)
    rig.valve(3.0)
    rig.run(0.5)
    p_up = rig.plant.pressure_bar
    assert p_up == pytest.approx(3.0 - width / 2, abs=1e-4)
    rig.valve(3.0 - 0.8 * width)  # inside the band: no change
    rig.run(0.5)
    # (the flow regulator is still creeping the last 20 ubar to its first target)
    assert rig.plant.pressure_bar == pytest.approx(p_up, abs=1e-6 if pneumatics == "lag"
                                                   else 1e-4)
    rig.valve(2.5)  # out of the band: follows, offset by half the band
    rig.run(0.5)
    assert rig.plant.pressure_bar == pytest.approx(2.5 + width / 2, abs=1e-4)


@BOTH
def test_setpoint_is_clamped_to_full_scale_and_supply(make_rig, pneumatics: str) -> None:
    rig = make_rig(regulator_max_bar=6.0, supply_bar=7.0, regulator_backlash_bar=0.0,
                   pneumatics=pneumatics)
    rig.valve(9.0)
    rig.run(0.5)
    assert rig.plant.pressure_bar == pytest.approx(6.0, abs=1e-3)
    rig = make_rig(regulator_max_bar=6.0, supply_bar=4.5, regulator_backlash_bar=0.0,
                   pneumatics=pneumatics)
    rig.valve(6.0)
    rig.run(0.5)
    assert rig.plant.pressure_bar == pytest.approx(4.5, abs=1e-3)
    rig.valve(-3.0)
    rig.run(0.5)
    # a regulator's exhaust vents the last hundredths of a bar slowly (the flow falls
    # with the pressure difference and the main stage closes as the error shrinks)
    assert rig.plant.pressure_bar == pytest.approx(0.0, abs=1e-3 if pneumatics == "lag"
                                                   else 0.03)


@BOTH
def test_zero_point_suppression_vents(make_rig, pneumatics: str) -> None:
    rig = make_rig(initial_pressure_bar=2.0, regulator_zero_bar=0.03, pneumatics=pneumatics)
    rig.valve(0.02)
    rig.run(0.5)
    assert rig.plant.pressure_bar < (1e-3 if pneumatics == "lag" else 0.01)


@BOTH
def test_initial_pressure_is_held_at_power_up(make_rig, pneumatics: str) -> None:
    rig = make_rig(initial_pressure_bar=2.5, load_kg=30.0, pneumatics=pneumatics)
    x0 = rig.plant.contraction
    rig.run(0.5)  # nothing written: the regulator holds what it had
    assert rig.read("m1.pressure") == pytest.approx(2.5, abs=0.02)
    assert rig.plant.contraction == pytest.approx(x0, abs=1e-4)  # at rest from the start


@BOTH
def test_supply_lost_pressure_cannot_rise_but_can_fall(make_rig, pneumatics: str) -> None:
    rig = make_rig(initial_pressure_bar=2.0, pneumatics=pneumatics)
    rig.driver.inject_fault("m1", "supply", "lost")
    rig.valve(4.0)
    rig.run(0.5)
    assert rig.plant.pressure_bar <= 2.0 + 1e-9
    assert rig.plant.pressure_bar > 1.9  # it holds
    rig.valve(1.0)
    rig.run(0.5)
    # without supply a flow regulator that vents past its target cannot fill back
    assert rig.plant.pressure_bar == pytest.approx(1.0, abs=0.02 if pneumatics == "lag"
                                                   else 0.05)
    rig.driver.clear_faults()
    rig.valve(4.0)
    rig.run(0.5)
    assert rig.plant.pressure_bar == pytest.approx(4.0, abs=0.02)


def test_exhaust_vents_fast_and_closing_it_restores(make_rig) -> None:
    tau_s = 0.015
    rig = make_rig(initial_pressure_bar=5.0, exhaust_vent_time_constant_s=tau_s)
    rig.write("m1.exhaust", 1.0)  # the regulator still asks for 5 bar: the exhaust valve wins
    samples = rig.run(0.1)
    k = rig.driver.input_index("m1.pressure")
    t_1e = next(t for t, v in samples if v[k] <= 5.0 / 2.718281828)
    assert t_1e == pytest.approx(tau_s, rel=0.1, abs=0.0015)
    t_5pct = next(t for t, v in samples if v[k] <= 0.25)
    assert t_5pct <= 0.050
    assert rig.plant.pressure_bar < 0.01
    rig.write("m1.exhaust", 0.0)
    rig.run(0.5)
    assert rig.plant.pressure_bar == pytest.approx(5.0, abs=0.02)
