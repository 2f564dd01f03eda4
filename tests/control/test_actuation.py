"""The actuation seam: today's regulator + exhaust behind the `Actuation` Protocol."""

from __future__ import annotations

from typing import Any

import pytest

from pamd.control.actuation import Actuation, RegulatorActuation
from pamd.tick import Flag


def test_the_regulator_actuation_writes_the_setpoint_and_vents_on_request(
        harness: Any) -> None:
    h = harness()
    h.step(0.01)
    act: Actuation = h.m1.actuation
    assert isinstance(act, RegulatorActuation)
    reg = h.sim.plant("m1").regulator
    assert act.write(2.0, 0.0, h.t, h.period_s, False) == 0
    assert reg.setpoint_bar == pytest.approx(2.0) and not reg.exhaust_open
    assert act.write(0.0, 0.0, h.t, h.period_s, True) == int(Flag.EXHAUST_OPEN)
    assert reg.exhaust_open and act.exhaust_open and act.switch_count == 1
    act.write(0.0, 0.0, h.t, h.period_s, True)  # stays open: no new switch
    act.write(1.0, 0.0, h.t, h.period_s, False)
    assert not reg.exhaust_open and act.switch_count == 2


def test_the_safe_outputs_follow_the_safe_pressure(harness: Any) -> None:
    h = harness()
    act = h.m1.actuation
    (valve, bar, unit), (exhaust, vent, _) = act.safe_outputs(0.0)
    assert (valve.name, bar, unit, exhaust.name, vent) == ("m1.valve", 0.0, "bar",
                                                          "m1.exhaust", 1.0)
    (_, bar, _), (_, vent, _) = act.safe_outputs(1.8)
    assert (bar, vent) == (1.8, 0.0)  # the load needs pressure: the exhaust stays shut


def test_the_tick_vents_only_at_a_safe_pressure_of_zero(harness: Any) -> None:
    h = harness(load_kg=30.0)  # 30 kg: the safe pressure is 0
    h.step(0.01)
    assert h.cmd("setpoint", muscle="m1", bar=2.0)["ok"]
    h.step(1.0)
    assert not h.m1.exhaust_open and h.m1.actuation.switch_count == 0
    assert h.cmd("stop")["ok"]
    h.keep = True
    h.step(2.0)
    flags = [int(r["m1"]["flags"]) & int(Flag.EXHAUST_OPEN) != 0 for r in h.records]
    assert any(flags) and not flags[0]  # opened once the ramp reached 0 bar
    toggles = sum(a != b for a, b in zip(flags, flags[1:], strict=False))
    assert h.m1.actuation.switch_count == toggles  # every switch is counted
