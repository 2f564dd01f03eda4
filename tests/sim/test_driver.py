"""The `sim` driver: protocol, options, determinism, load changes, faults,
numerical stability and cost per step."""

from __future__ import annotations

import dataclasses
import itertools
import math
import typing

import pytest
from pamd.drivers import load_driver_class
from pamd.drivers.sim import SimDriver

from pamd.muscle_type import equilibrium_contraction, force_model
from pamd.sim.options import SimMuscleOptions, SimOptions
from pamd.wire.errors import DriverError

# --- protocol and options -------------------------------------------------------


def test_registered_as_sim_and_steps_with_the_loop() -> None:
    cls = load_driver_class("sim")  # the protocol itself: tests/drivers/test_contract.py
    assert cls is SimDriver
    assert cls.steps_with_loop is True
    assert cls.options_type is SimOptions


def test_empty_options_give_one_muscle_m1() -> None:
    drv = SimDriver("sim", SimOptions())
    # the muscle's, then the rig's safety chain (pamd.loop.safety.chain)
    assert [c.name for c in drv.input_channels] == ["m1.pressure", "m1.force", "m1.length",
                                                     "safety_chain", "supply", "reset"]
    assert [c.unit for c in drv.input_channels] == ["bar", "N", "mm", "", "bar", ""]
    assert [c.name for c in drv.output_channels] == ["m1.valve", "m1.exhaust", "heartbeat"]
    assert drv.is_absolute(drv.input_index("m1.length"))


@pytest.mark.parametrize("cls", [SimOptions, SimMuscleOptions])
def test_every_option_is_documented_and_has_a_default(cls) -> None:
    assert dataclasses.fields(cls)
    assert cls.__dataclass_params__.frozen  # type: ignore[attr-defined]
    cls()  # every field has a default
    hints = typing.get_type_hints(cls)
    for f in dataclasses.fields(cls):
        doc = f.metadata.get("doc", "")
        assert doc.endswith(".") and len(doc) > 10, f.name
        if "min" in f.metadata and "max" in f.metadata and f.default is not None:
            assert f.metadata["min"] <= f.default <= f.metadata["max"], f.name
        assert hints[f.name] is not None


def test_bad_muscle_lists_are_refused() -> None:
    twice = (SimMuscleOptions(name="a"), SimMuscleOptions(name="a"))
    with pytest.raises(DriverError, match="used twice"):
        SimDriver("sim", SimOptions(muscles=twice))
    crossed = (SimMuscleOptions(stop_stretch_contraction=0.1, stop_contraction=0.0),)
    with pytest.raises(DriverError, match="stop_stretch_contraction"):
        SimDriver("sim", SimOptions(muscles=crossed))


def test_two_muscles_have_their_own_channels_and_physics(make_rig) -> None:
    rig = make_rig(SimMuscleOptions(name="a", load_kg=15.0), SimMuscleOptions(name="b"))
    drv = rig.driver
    assert drv.input_index("b.length") == 5
    assert drv.output_index("b.exhaust") == 3
    rig.write("b.valve", 4.0)
    rig.run(1.0)
    assert abs(drv.plant("a").pressure_bar) < 1e-9
    assert drv.plant("b").pressure_bar == pytest.approx(4.0, abs=0.02)
    assert rig.read("a.pressure") != rig.read("b.pressure")


def test_stamps_are_the_clock_at_the_end_of_advance(make_rig) -> None:
    rig = make_rig()
    rig.step(0.001)
    assert rig.driver.in_stamps_s == [0.001] * 6  # the muscle's and the chain's
    rig.step(0.003)  # after skipped periods
    assert rig.driver.in_stamps_s == [0.004] * 6
    assert rig.plant.t_s == pytest.approx(0.004)


def test_write_never_raises_on_nan_and_counts_it(make_rig) -> None:
    rig = make_rig()
    rig.valve(math.nan)
    rig.run(0.1)
    assert rig.plant.regulator.setpoint_bar == 0.0
    assert rig.driver.health().counters["dropped_writes"] == 1


# --- determinism and load changes -------------------------------------------------


def _script(rig) -> list[list[float]]:
    out = []
    for k in range(600):
        if k % 50 == 0:
            rig.valve((k // 50) % 6)
        rig.write("m1.exhaust", 1.0 if 400 <= k < 450 else 0.0)
        rig.step(0.001 if k < 300 else 0.002)
        out.append(list(rig.driver.in_values))
    return out


def test_same_seed_same_readings_other_seed_other_noise(make_rig) -> None:
    a = _script(make_rig(seed=7))
    b = _script(make_rig(seed=7))
    c = _script(make_rig(seed=8))
    assert a == b
    assert a != c
    # only the noise differs: lengths (quantised, noise-free) agree
    assert [r[2] for r in a] == [r[2] for r in c]


def test_load_change_while_running_moves_the_equilibrium(make_rig) -> None:
    rig = make_rig(load_kg=30.0, friction_n_per_bar=0.0, friction_per_tension=0.0,
                   regulator_backlash_bar=0.0)
    rig.valve(3.0)
    rig.run(1.5)
    model = force_model("map")
    assert rig.contraction_read() == pytest.approx(
        equilibrium_contraction(model, 3.0, 30.0), abs=0.003
    )
    rig.driver.set_load_kg("m1", 50.0)
    rig.run(2.0)
    assert rig.contraction_read() == pytest.approx(
        equilibrium_contraction(model, 3.0, 50.0), abs=0.003
    )
    assert rig.read("m1.force") == pytest.approx(50.0 * 9.80665, abs=3.0)


# --- faults -----------------------------------------------------------------------


def _moving_rig(make_rig):
    """A rig whose every reading changes: pressurising from 0 to 4 bar."""
    rig = make_rig()
    rig.run(0.01)
    rig.valve(4.0)
    return rig


@pytest.mark.parametrize("signal", ["pressure", "force", "length"])
def test_stuck_sensor_freezes_value_but_stamps_advance(make_rig, signal: str) -> None:
    rig = _moving_rig(make_rig)
    ch = f"m1.{signal}"
    frozen = rig.read(ch)
    rig.driver.inject_fault("m1", signal, "stuck")
    rig.run(0.3)
    assert rig.read(ch) == frozen
    assert rig.stamp(ch) == pytest.approx(rig.t_s)
    others = [c.name for c in rig.driver.input_channels if c.name != ch]
    assert all(rig.stamp(o) == pytest.approx(rig.t_s) for o in others)
    rig.driver.clear_faults()
    rig.step()
    assert rig.read(ch) != frozen


@pytest.mark.parametrize("signal", ["pressure", "force", "length"])
def test_dead_sensor_reads_zero_and_stamps_advance(make_rig, signal: str) -> None:
    rig = _moving_rig(make_rig)
    ch = f"m1.{signal}"
    rig.driver.inject_fault("m1", signal, "dead")
    rig.run(0.1)
    assert rig.read(ch) == 0.0
    assert rig.stamp(ch) == pytest.approx(rig.t_s)
    rig.driver.clear_faults()
    rig.step()
    assert rig.read(ch) != 0.0


@pytest.mark.parametrize("signal", ["pressure", "force", "length"])
def test_silent_sensor_stops_its_stamps(make_rig, signal: str) -> None:
    rig = _moving_rig(make_rig)
    ch = f"m1.{signal}"
    rig.driver.inject_fault("m1", signal, "silent")
    t_fault = rig.t_s
    rig.run(0.2)
    assert rig.stamp(ch) == pytest.approx(t_fault)
    other = "m1.force" if signal != "force" else "m1.pressure"
    assert rig.stamp(other) == pytest.approx(rig.t_s)
    rig.driver.clear_faults()
    rig.step()
    assert rig.stamp(ch) == pytest.approx(rig.t_s)


def test_driver_error_sets_fault_stops_readings_and_drops_writes(make_rig) -> None:
    rig = make_rig()
    rig.run(0.05)
    rig.driver.inject_fault("*", "driver", "error")
    assert isinstance(rig.driver.fault, str) and "sim" in rig.driver.fault
    assert rig.driver.health().ok is False
    t_fault = rig.t_s
    rig.valve(3.0)
    rig.run(0.3)
    assert rig.driver.in_stamps_s == [pytest.approx(t_fault)] * 6
    assert abs(rig.plant.pressure_bar) < 1e-9  # the failed device took no output
    rig.driver.clear_faults()
    assert rig.driver.fault is None and rig.driver.health().ok
    rig.valve(3.0)
    rig.run(0.3)
    assert rig.read("m1.pressure") == pytest.approx(3.0, abs=0.05)


def test_unknown_faults_are_refused(make_rig) -> None:
    drv = make_rig().driver
    with pytest.raises(KeyError, match="m9"):
        drv.inject_fault("m9", "force", "stuck")
    with pytest.raises(ValueError, match="signal"):
        drv.inject_fault("m1", "temperature", "stuck")
    with pytest.raises(ValueError, match="fault"):
        drv.inject_fault("m1", "force", "melted")
    # each signal takes only its own kinds (pamd.sim.faults.FAULT_KINDS), named
    with pytest.raises(ValueError, match="valve fault must be 'stuck', got 'lost'"):
        drv.inject_fault("m1", "valve", "lost")
    with pytest.raises(ValueError, match="'open' or 'closed', got 'stuck'"):
        drv.inject_fault("*", "safety_chain", "stuck")
    with pytest.raises(ValueError, match="unknown sensor fault 'lost'; use one of dead, stuck"):
        drv.inject_fault("m1", "pressure", "lost")
    with pytest.raises(ValueError, match="unknown signal 'loop'"):  # a stall: scheduled only
        drv.inject_fault("*", "loop", "stall")
    assert drv.fault is None and not drv.chain_open and drv.health().ok  # nothing took


# --- numerics -----------------------------------------------------------------------


@pytest.mark.parametrize("dt_s", [0.001, 0.002])
@pytest.mark.parametrize("load_kg", [0.0, 100.0])
@pytest.mark.parametrize("pressure_bar", [0.0, 6.0])
def test_stable_at_the_extremes(make_rig, dt_s, load_kg, pressure_bar) -> None:
    """From the other end of the pressure range: finite, inside the stops, at rest."""
    rig = make_rig(load_kg=load_kg, initial_pressure_bar=6.0 - pressure_bar)
    o, p = rig.plant.options, rig.plant  # the stops: the type's (the options give none)
    rig.valve(pressure_bar)
    samples = rig.run(2.0, dt_s)
    for _, values in samples:
        assert all(math.isfinite(v) for v in values)
        assert abs(values[1]) < 5000.0
        x = 1.0 - values[2] / o.nominal_length_mm
        assert p.stop_stretch_contraction - 1e-4 <= x <= p.stop_contraction + 1e-4
    assert abs(rig.plant.velocity_mm_s) < 0.5
    if load_kg == 0.0 and pressure_bar == 6.0:  # force runs out only past 25 %: on the stop
        assert rig.plant.contraction == pytest.approx(p.stop_contraction)
    if load_kg == 100.0 and pressure_bar == 0.0:  # over-stretched: caught by the stop
        assert rig.plant.contraction == pytest.approx(p.stop_stretch_contraction)


@pytest.mark.parametrize(("load_kg", "start_bar", "end_bar"), [(0.0, 0.0, 6.0), (100.0, 2.0, 6.0)])
def test_coarse_steps_track_a_fine_reference(make_rig, load_kg, start_bar, end_bar) -> None:
    """dt = 1 ms and 2 ms against dt = 0.1 ms on a full step response: the contraction
    trajectories agree within 0.4 % (0.8 mm) and end at the same place."""
    ref = make_rig(load_kg=load_kg, initial_pressure_bar=start_bar)
    ref.valve(end_bar)
    fine = [ref.plant.contraction for _ in ref.run(1.0, 0.0001)]
    for dt_s in (0.001, 0.002):
        rig = make_rig(load_kg=load_kg, initial_pressure_bar=start_bar)
        rig.valve(end_bar)
        stride = round(dt_s / 0.0001)
        dev = 0.0
        for k, _ in enumerate(rig.run(1.0, dt_s)):
            dev = max(dev, abs(rig.plant.contraction - fine[(k + 1) * stride - 1]))
        assert dev < 0.004, f"dt {dt_s}: {dev * 100:.3f} %"
        assert rig.plant.contraction == pytest.approx(fine[-1], abs=0.002)


def test_a_long_stall_is_integrated_in_short_steps(make_rig) -> None:
    rig = make_rig(load_kg=100.0)
    rig.valve(6.0)
    rig.step(0.5)  # one advance after a half-second stall
    assert math.isfinite(rig.plant.contraction)
    rig.run(2.0)
    assert rig.plant.contraction == pytest.approx(
        equilibrium_contraction(force_model("map"), 6.0, 100.0), abs=0.01
    )


UNDAMPED = {
    "damping_contracting_n_s_per_m": 0.0,
    "damping_relaxing_n_s_per_m": 0.0,
    "friction_n_per_bar": 0.0,
    "friction_per_tension": 0.0,
}


@pytest.mark.parametrize("dt_s", [0.001, 0.002])
def test_stable_without_damping_and_with_the_smallest_moving_mass(make_rig, dt_s) -> None:
    """No damper, no friction, 0 kg and 10 g moving: the muscle's stiffness alone
    (~125 N/mm) would make an explicit step explode; here it must stay bounded."""
    rig = make_rig(load_kg=0.0, moving_mass_kg=0.01, initial_pressure_bar=1.0, **UNDAMPED)
    rig.valve(3.0)
    for _, values in rig.run(1.0, dt_s):
        assert all(math.isfinite(v) for v in values)
        assert abs(values[1]) < 5000.0
    assert rig.plant.contraction == pytest.approx(
        equilibrium_contraction(force_model("map"), rig.plant.pressure_bar, 0.0), abs=0.003
    )


def test_hard_stop_does_not_bounce(make_rig) -> None:
    """100 kg vented without damping falls onto the stretch stop and stays there."""
    rig = make_rig(load_kg=100.0, initial_pressure_bar=4.0, **UNDAMPED)
    stop = rig.plant.stop_stretch_contraction
    rig.valve(0.0)
    rig.run(1.0)
    xs = [rig.plant.contraction for _ in rig.run(0.5)]
    assert max(xs) - min(xs) < 1e-9
    assert xs[-1] == pytest.approx(stop)


def test_write_to_a_missing_channel_is_an_index_error(make_rig) -> None:
    drv = make_rig().driver
    with pytest.raises(IndexError):
        drv.write(3, 1.0)  # 0, 1: the muscle's valve and exhaust; 2: the heartbeat
    with pytest.raises(IndexError):
        drv.write(-1, 1.0)


def test_a_late_clock_read_inside_a_tick_keeps_the_motion_and_the_stamps_together() -> None:
    """A reading shows the rig as it was at its stamp, and a muscle moves no faster
    than its own dynamics between two stamps. On a busy PC the loop's process can be
    descheduled between its wake-up and the driver's clock read: that tick's stamp is
    then late (here 240 ms). The loop's next tick wakes late too and, skipping the
    missed periods, asks for a step over the whole gap, though its stamp follows the
    late one by a single period. Stepped by the loop's step, the plant moved a quarter
    second between stamps 5 ms apart ("length jumped +13 mm in 5 ms", a false fault seen
    under load); stepped to its clock, it moves with its stamps."""
    period = 0.005
    drv = SimDriver("sim", SimOptions(muscles=(SimMuscleOptions(load_kg=20.0),)))
    deadline_s, late_s = [0.0], [0.0]
    drv.open(lambda: deadline_s[0] + 50e-6 + late_s[0])  # read 50 us after the wake-up
    plant = drv.plant("m1")
    length = drv.input_index("m1.length")
    drv.write(drv.output_index("m1.valve"), 5.0)  # filling: the muscle contracts
    seen: list[tuple[float, float, float]] = []  # (stamp, length, plant's time - stamp)
    top_speed_mm_s = 0.0
    dt_s = period
    for k in range(120):
        deadline_s[0] += dt_s
        late_s[0] = 0.240 if k == 20 else 0.0  # descheduled inside tick 20
        drv.advance(dt_s)
        stamp = drv.in_stamps_s[length]
        seen.append((stamp, drv.in_values[length], plant.t_s - stamp))
        top_speed_mm_s = max(top_speed_mm_s, abs(plant.velocity_mm_s))
        missed = int((late_s[0] + 50e-6) / period)  # the loop skips what it missed
        dt_s = period * (missed + 1)
    assert seen[21][0] - seen[20][0] == pytest.approx(period, abs=1e-6)  # the case itself
    offsets = [s[2] for s in seen]
    assert max(offsets) - min(offsets) < 1e-9, "a reading not at its plant's time"
    for (t0, len0, _), (t1, len1, _) in itertools.pairwise(seen):
        assert abs(len1 - len0) <= 1.5 * top_speed_mm_s * (t1 - t0) + 0.02, (t0, len1 - len0)
    assert top_speed_mm_s > 20.0  # it did move, fast, through the late tick
