"""The simulated rig with air that flows ('flow' pneumatics), stiction and drift,
seen through the sim driver's sensors."""

from __future__ import annotations

from dataclasses import replace

import pytest
from pamd.drivers.sim import SimDriver

from pamd.sim.options import SimMuscleOptions, SimOptions
from tests.sim.rig import Rig


def _t63_ms(make_rig, **kw) -> float:
    """0 -> 3 bar into the muscle at rest under its load, from the true pressure."""
    rig = make_rig(pneumatics="flow", **kw)
    rig.run(0.3)
    p0 = rig.plant.pressure_bar
    rig.valve(3.0)
    for k in range(1, 1000):
        rig.step()
        if rig.plant.pressure_bar >= p0 + 0.632 * (3.0 - p0):
            return float(k)
    raise AssertionError("the pressure never reached 63 % of the step")


@pytest.mark.parametrize("load_kg", [0.0, 30.0, 80.0])
def test_step_t63_is_30_to_80_ms_and_lengthens_with_volume(make_rig, load_kg) -> None:
    base = _t63_ms(make_rig, load_kg=load_kg)
    more_hose = _t63_ms(make_rig, load_kg=load_kg, dead_volume_cm3=60.0)
    longer_muscle = _t63_ms(make_rig, load_kg=load_kg, nominal_length_mm=300.0)
    assert 30.0 <= base <= 80.0
    assert base < longer_muscle and base < more_hose


def test_a_muscle_that_contracts_draws_air_the_pressure_dips_without_it(make_rig) -> None:
    """With the regulator unpowered (holding), a muscle pushed shorter by a lighter
    load gains volume and so loses pressure; the lag model knows no such thing."""
    rig = make_rig(pneumatics="flow", load_kg=60.0)
    rig.valve(4.0)
    rig.run(1.0)
    held = rig.plant.pressure_bar
    rig.plant.regulator.powered = False
    rig.driver.set_load_kg("m1", 10.0)
    rig.run(1.0)
    assert rig.plant.contraction > 0.05
    assert rig.plant.pressure_bar < held - 0.3


def _lowest_supply_bar(n_muscles: int) -> tuple[float, float]:
    """(lowest supply line pressure while n muscles fill 0 -> 6 bar at once, the
    line pressure 3 s later)."""
    muscles = tuple(SimMuscleOptions(name=f"m{k}", pneumatics="flow") for k in range(n_muscles))
    drv = SimDriver("sim", SimOptions(muscles=muscles, supply_line_volume_l=0.5))
    step = Rig(driver=drv).step
    assert drv.supply_line is not None
    for k in range(n_muscles):
        drv.write(2 * k, 6.0)
    low = drv.supply_line.pressure_bar
    for _ in range(300):
        step(0.001)
        low = min(low, drv.supply_line.pressure_bar)
    for _ in range(3000):
        step(0.001)
    return low, drv.supply_line.pressure_bar


def test_the_shared_supply_line_sags_when_muscles_fill_at_once() -> None:
    low_one, after_one = _lowest_supply_bar(1)
    low_three, after_three = _lowest_supply_bar(3)
    assert low_three < low_one - 0.05 and low_one < 7.0
    assert after_one == pytest.approx(7.0, abs=0.01)  # refilled from the compressor
    assert after_three == pytest.approx(7.0, abs=0.01)


def test_stiction_widens_the_sticking_band(make_rig) -> None:
    """A slow pressure ramp: with breakaway friction above sliding the muscle stays
    put longer before it moves (stick-slip), so the first motion comes later."""
    def first_motion_s(ratio: float) -> float:
        rig = make_rig(load_kg=30.0, stiction_ratio=ratio, initial_pressure_bar=3.0)
        rig.run(1.0)
        x0 = rig.plant.contraction
        for k in range(1, 5000):
            rig.valve(3.0 + 0.5 * k / 1000)
            rig.step()
            if abs(rig.plant.contraction - x0) > 0.002:
                return k / 1000
        raise AssertionError("never moved")

    assert first_motion_s(2.0) > first_motion_s(1.0) + 0.02


def test_force_drift_weakens_the_muscle_over_rig_time(make_rig) -> None:
    rig = make_rig(force_drift_per_hour=-0.6)  # 10 % in 10 minutes
    f0 = rig.plant.static_force_n(4.0, 0.0)
    rig.run(60.0, dt_s=0.002)
    assert rig.plant.static_force_n(4.0, 0.0) == pytest.approx(0.99 * f0, rel=1e-3)


def test_a_slow_input_is_stamped_with_when_it_was_sampled(make_rig) -> None:
    """An ADAM-class pressure input: 10 samples/s, 20 ms to deliver. The driver's
    stamp is the sample's time, so the loop sees its true age (up to 120 ms)."""
    rig = make_rig(pressure_sample_period_s=0.1, pressure_latency_s=0.02)
    ages = []
    for _ in range(1000):
        rig.step()
        ages.append(rig.t_s - rig.stamp("m1.pressure"))
    assert min(ages[50:]) == pytest.approx(0.02, abs=1e-6)
    assert max(ages[200:]) == pytest.approx(0.12, abs=2e-3)
    assert rig.t_s - rig.stamp("m1.force") == 0.0  # the other inputs: fresh


def test_ideal_sensors_read_as_before(make_rig) -> None:
    """Sampling at every step without latency gives the same readings as the plain
    path (the noise draws in the same order)."""
    plain = make_rig(seed=3)
    sampled = make_rig(seed=3, force_filter_s=0.0, length_latency_s=1e-12)
    for _ in range(200):
        plain.valve(2.0)
        sampled.valve(2.0)
        plain.step()
        sampled.step()
    assert plain.read("m1.pressure") == sampled.read("m1.pressure")
    assert plain.read("m1.force") == sampled.read("m1.force")


def test_a_10_samples_per_second_input_is_stale_for_a_50_ms_timeout(sim_config) -> None:
    """Through the whole controller: the loop sees each sample's true age, so a
    pressure input converting every 100 ms faults a rig whose timeout is 50 ms,
    naming the input; at 20 ms per sample the same rig runs. (The config refuses a
    simulated sensor slower than its timeout, tests/config/test_actuation.py; here the
    device is slower than its config says, as real hardware can be.)"""
    from pamd.loop.harness import Harness

    def run(period_s: float) -> Harness:
        cfg = sim_config(safety={"signal_timeout_s": 0.05})
        drv = cfg.rig.drivers[0]
        muscle = replace(drv.options.muscles[0], pressure_sample_period_s=period_s)
        drivers = (replace(drv, options=replace(drv.options, muscles=(muscle,))),)
        h = Harness(replace(cfg, rig=replace(cfg.rig, drivers=drivers)))
        h.step(1.0)
        h.rig.close()
        return h

    slow = run(0.1)
    assert slow.state == "FAULT"
    assert "pressure" in slow.ctrl.supervisor.fault_reason
    assert "stale" in slow.ctrl.supervisor.fault_reason
    assert run(0.02).state == "IDLE"
