"""Air that flows: ISO 6358 orifices, chambers, the supply line and the VPPM device."""

from __future__ import annotations

import math
from dataclasses import replace

import pytest

from pamd.sim.options import SimMuscleOptions
from pamd.sim.pneumatics import (
    BAR_PA,
    LAMINAR_RATIO,
    P_ATM_PA,
    Chamber,
    MuscleVolume,
    SupplyLine,
    conductance_from_nominal_flow,
    orifice_flow_kg_s,
)
from pamd.sim.vppm import FlowRegulator

C = 2.0e-8  # m^3/(s Pa)
B = 0.3
DT = 0.001


def abs_pa(bar: float) -> float:
    return bar * BAR_PA + P_ATM_PA


def test_choked_flow_does_not_depend_on_the_downstream_pressure() -> None:
    p1 = abs_pa(6.0)
    q_low = orifice_flow_kg_s(C, B, p1, 0.1 * p1)
    q_at_b = orifice_flow_kg_s(C, B, p1, B * p1)
    assert q_low == pytest.approx(q_at_b)
    assert orifice_flow_kg_s(C, B, p1, 0.5 * p1) < q_at_b  # subsonic: less


def test_flow_is_continuous_antisymmetric_and_zero_without_a_difference() -> None:
    p1 = abs_pa(4.0)
    below = orifice_flow_kg_s(C, B, p1, p1 * (LAMINAR_RATIO - 1e-9))
    above = orifice_flow_kg_s(C, B, p1, p1 * (LAMINAR_RATIO + 1e-9))
    assert below == pytest.approx(above, rel=1e-5)
    assert orifice_flow_kg_s(C, B, p1, p1) == 0.0
    assert orifice_flow_kg_s(C, B, 2e5, 5e5) == -orifice_flow_kg_s(C, B, 5e5, 2e5)


def test_conductance_from_nominal_flow_gives_the_nominal_flow_back() -> None:
    c = conductance_from_nominal_flow(700.0, B)
    q_kg_s = orifice_flow_kg_s(c, B, abs_pa(6.0), abs_pa(5.0))
    assert q_kg_s / 1.185 * 60000.0 == pytest.approx(700.0, rel=1e-9)


def test_muscle_volume_follows_the_braid_geometry_table() -> None:
    v = MuscleVolume(dead_volume_cm3=5.0)
    assert v.volume_m3(0.0) * 1e6 == pytest.approx(67.8)
    assert v.volume_m3(0.125) * 1e6 == pytest.approx(5.0 + (92.9 + 103.6) / 2)
    assert v.volume_m3(0.25) * 1e6 == pytest.approx(121.9)
    assert v.volume_m3(-0.04) < v.volume_m3(0.0)  # a stretched muscle holds less


def test_two_chambers_exchange_air_and_conserve_it() -> None:
    """Isothermal (n = 1): the air p V / (R T) leaving one chamber is the air the
    other receives, step after step, until the pressures meet."""
    a = Chamber(100e-6, abs_pa(6.0), polytropic=1.0)
    b = Chamber(50e-6, abs_pa(0.0), polytropic=1.0)
    total0 = a.air_mass_kg + b.air_mass_kg
    for _ in range(2000):
        q = orifice_flow_kg_s(C, B, a.pressure_pa, b.pressure_pa)
        a.step(1e-4, -q, a.volume_m3)
        b.step(1e-4, q, b.volume_m3)
    assert a.air_mass_kg + b.air_mass_kg == pytest.approx(total0, rel=1e-12)
    assert a.pressure_pa == pytest.approx(b.pressure_pa, rel=1e-3)


def test_a_contracting_muscle_loses_pressure_unless_air_flows_in() -> None:
    ch = Chamber(80e-6, abs_pa(3.0), polytropic=1.2)
    p = ch.step(DT, 0.0, 100e-6)
    assert p == pytest.approx(abs_pa(3.0) * (80 / 100) ** 1.2)


def _rig(x: float = 0.1, n: float = 1.0, supply: SupplyLine | None = None,
         **options: float) -> tuple[SupplyLine, FlowRegulator]:
    """A default simulated muscle's regulator (its options changed by `options`)."""
    supply = SupplyLine() if supply is None else supply
    o = replace(SimMuscleOptions(pneumatics="flow"), polytropic_exponent=n, **options)
    return supply, FlowRegulator.from_options(o, supply, x, 0.0)


def test_regulator_and_supply_conserve_air() -> None:
    """Compressor in = line + muscle + what went out of the exhausts, while the
    regulator fills, holds, vents and the muscle's volume changes."""
    supply, reg = _rig(n=1.0)
    m0 = supply.chamber.air_mass_kg + reg.chamber.air_mass_kg
    x = 0.1
    for k in range(3000):
        if k == 0:
            reg.set_setpoint(4.0)
        elif k == 1000:
            reg.set_setpoint(1.0)
        elif k == 2000:
            reg.exhaust_open = True
        x = 0.1 + 0.05 * math.sin(k * 0.01)
        reg.step(DT, x)
        supply.step(DT)
    m1 = supply.chamber.air_mass_kg + reg.chamber.air_mass_kg
    assert reg.vented_kg > 0.0
    assert m1 == pytest.approx(m0 + supply.delivered_kg - reg.vented_kg, rel=1e-9)


def test_a_blocked_regulator_holds_its_pressure() -> None:
    """Power lost: the main stage closes and the muscle keeps its air (VPPM holds)."""
    supply, reg = _rig()
    reg.set_setpoint(3.0)
    for _ in range(500):
        reg.step(DT, 0.1)
        supply.step(DT)
    held = reg.pressure_bar
    reg.powered = False
    reg.set_setpoint(0.0)
    for _ in range(2000):
        reg.step(DT, 0.1)
        supply.step(DT)
    assert reg.pressure_bar == held


def test_without_supply_the_pressure_cannot_rise() -> None:
    supply, reg = _rig()
    reg.supply_ok = False
    reg.set_setpoint(5.0)
    for _ in range(500):
        reg.step(DT, 0.1)
        supply.step(DT)
    assert reg.pressure_bar == pytest.approx(0.0, abs=1e-12)


def _t63_ms(x: float) -> float:
    """0 -> 3 bar into a muscle held at contraction x."""
    supply, reg = _rig(x=x, n=1.2)
    reg.set_setpoint(3.0)
    for k in range(1, 1000):
        if reg.step(DT, x) >= 0.632 * 3.0:
            return k * DT * 1000.0
        supply.step(DT)
    raise AssertionError("never reached 63 %")


def test_step_response_is_tens_of_ms_and_lengthens_with_volume() -> None:
    t_small, t_large = _t63_ms(0.0), _t63_ms(0.25)
    assert 30.0 <= t_small < t_large <= 80.0


def test_a_shared_supply_sags_more_when_several_muscles_fill_at_once() -> None:
    def lowest_supply_bar(n_muscles: int) -> float:
        supply = SupplyLine()
        regs = [_rig(supply=supply)[1] for _ in range(n_muscles)]
        low = supply.pressure_bar
        for r in regs:
            r.set_setpoint(6.0)
        for _ in range(300):
            for r in regs:
                r.step(DT, 0.1)
            supply.step(DT)
            low = min(low, supply.pressure_bar)
        return low

    one, four = lowest_supply_bar(1), lowest_supply_bar(4)
    assert four < one < 7.0
