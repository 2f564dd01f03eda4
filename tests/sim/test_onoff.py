"""On/off solenoid valves (seed 004): switching delays, inflate / hold / exhaust,
air conservation, and the sim driver's digital outputs."""

from __future__ import annotations

from dataclasses import replace

import pytest
from pamd.drivers.sim import SimDriver

from pamd.sim.options import SimMuscleOptions, SimOptions
from pamd.sim.pneumatics import SupplyLine
from pamd.sim.solenoid import OnOffValves, SolenoidValve
from tests.sim.rig import Rig

DT = 0.001


def test_a_valve_opens_and_closes_after_its_delays() -> None:
    v = SolenoidValve(on_delay_s=0.002, off_delay_s=0.004)
    v.command(True)
    opened = [v.step(k * 0.0005) for k in range(10)]
    assert opened.index(True) == 4  # 2 ms after the command
    v.command(False)
    closed = [v.step(0.005 + k * 0.0005) for k in range(12)]
    assert closed.index(False) == 8  # 4 ms after the release
    assert v.switchings == 2


def test_a_command_taken_back_within_the_delay_never_moves_the_spool() -> None:
    v = SolenoidValve(on_delay_s=0.003, off_delay_s=0.004)
    v.command(True)
    v.step(0.0)
    v.step(0.001)
    v.command(False)
    for k in range(2, 20):
        assert not v.step(k * 0.001)
    assert v.switchings == 0


def _valves(n: float = 1.2) -> tuple[SupplyLine, OnOffValves]:
    supply = SupplyLine()
    o = replace(SimMuscleOptions(actuation="onoff"), polytropic_exponent=n)
    return supply, OnOffValves.from_options(o, supply, 0.1, 0.0)


def _run(supply: SupplyLine, valves: OnOffValves, seconds: float, x: float = 0.1) -> None:
    for _ in range(round(seconds / DT)):
        valves.step(DT, x)
        supply.step(DT)


def test_inflate_hold_exhaust() -> None:
    supply, valves = _valves()
    valves.set_inflate(True)
    _run(supply, valves, 0.2)
    filled = valves.pressure_bar
    assert 0.5 < filled < 7.0
    valves.set_inflate(False)
    _run(supply, valves, 0.01)  # the inflate valve closes 4 ms after its release
    held = valves.pressure_bar
    _run(supply, valves, 1.0)
    assert valves.pressure_bar == held  # shut in: not a molecule moves
    valves.exhaust_open = True
    _run(supply, valves, 3.0)
    assert valves.pressure_bar < 0.05 * held
    valves.set_inflate(True)  # both energised: the inflate valve wins
    _run(supply, valves, 0.2)
    assert valves.pressure_bar > 0.5


def test_on_off_valves_conserve_air() -> None:
    supply, valves = _valves(n=1.0)
    m0 = supply.chamber.air_mass_kg + valves.chamber.air_mass_kg
    for k in range(40):  # 25 Hz PWM-like switching while the muscle moves
        valves.set_inflate(k % 2 == 0)
        valves.exhaust_open = k % 4 == 3
        for j in range(20):
            valves.step(DT, 0.1 + 0.001 * j)
            supply.step(DT)
    m1 = supply.chamber.air_mass_kg + valves.chamber.air_mass_kg
    assert valves.switchings > 30
    assert m1 == pytest.approx(m0 + supply.delivered_kg - valves.vented_kg, rel=1e-9)


def test_the_sim_driver_gives_an_onoff_muscle_digital_valve_outputs() -> None:
    drv = SimDriver("sim", SimOptions(muscles=(SimMuscleOptions(actuation="onoff"),)))
    names = [c.name for c in drv.output_channels]
    assert names == ["m1.inflate", "m1.exhaust", "heartbeat"]  # + the safety chain's
    step = Rig(driver=drv).step
    plant = drv.plant("m1")
    drv.write(drv.output_index("m1.inflate"), 1.0)
    for _ in range(300):
        step(DT)
    assert plant.pressure_bar > 1.0
    drv.write(drv.output_index("m1.inflate"), 0.0)
    drv.write(drv.output_index("m1.exhaust"), 1.0)
    for _ in range(3000):
        step(DT)
    assert plant.pressure_bar < 0.1
    assert drv.health().counters["valve_switchings"] == 3
    with pytest.raises(TypeError, match="on/off valves"):
        plant.set_setpoint(2.0)
