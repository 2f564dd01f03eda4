"""On/off valves in the tick (issue #14): `OnOffActuation` behind the actuation seam,
chosen from the muscle's config; PWM follows the command, holds at rest, vents to the
safe state, and a stuck valve ends in the tracking fault and the safe state."""

from __future__ import annotations

from typing import Any

import pytest

from pamd.loop.control.actuation import OnOffActuation
from pamd.loop.harness import Harness
from pamd.wire.tick import Flag, State
from tests.safety.conftest import onoff_muscles, sim_driver


def onoff_rig(harness: Any, load_kg: float = 30.0, initial_bar: float = 0.0,
              faults: list[dict[str, Any]] | None = None, **changes: Any) -> Harness:
    h: Harness = harness(load_kg, drivers=sim_driver(load_kg, initial_bar, faults, "onoff"),
                         muscles=onoff_muscles(load_kg), **changes)
    h.step(0.01)
    return h


def test_an_onoff_muscle_gets_pwm_actuation_and_no_pid(harness: Any) -> None:
    h = onoff_rig(harness)
    act = h.m1.actuation
    assert isinstance(act, OnOffActuation)
    assert (act.inflate.name, act.exhaust.name) == ("m1.inflate", "m1.exhaust")
    pid = h.m1.pressure_loop.pid
    assert (pid.kp, pid.ki, pid.kd, h.m1.pressure_loop.rate_feedforward_s) == (0, 0, 0, 0)


def test_pwm_reaches_a_setpoint_and_then_leaves_the_valves_alone(harness: Any) -> None:
    h = onoff_rig(harness)
    assert h.cmd("setpoint", muscle="m1", bar=3.0)["ok"]
    h.step(3.0)
    plant = h.sim.plant("m1")
    assert plant.pressure_bar == pytest.approx(3.0, abs=0.05)
    act = h.m1.actuation
    before = act.switches()
    h.step(5.0)  # at rest: the dead band holds both valves shut
    after = act.switches()
    assert after["inflate"] - before["inflate"] <= 5 * 5  # <= 1 per second per valve
    assert after["exhaust"] - before["exhaust"] <= 5 * 5
    assert plant.pressure_bar == pytest.approx(3.0, abs=0.05)


def test_the_safe_outputs_hold_or_vent(harness: Any) -> None:
    act = onoff_rig(harness).m1.actuation
    (inflate, a, _), (exhaust, b, _) = act.safe_outputs(1.8)
    assert (inflate.name, a, exhaust.name, b) == ("m1.inflate", 0.0, "m1.exhaust", 0.0)
    (_, a, _), (_, b, _) = act.safe_outputs(0.0)
    assert (a, b) == (0.0, 1.0)  # the load needs no pressure: the exhaust vents


def test_a_stop_at_a_safe_pressure_of_0_vents_with_the_exhaust_held_open(
        harness: Any) -> None:
    h = onoff_rig(harness, 30.0)  # 30 kg: the safe pressure is 0
    assert h.cmd("setpoint", muscle="m1", bar=3.0)["ok"]
    h.step(2.0)
    assert h.cmd("stop")["ok"]
    h.step(2.0)  # the ramp down at the slew limit reaches 0 bar
    act = h.m1.actuation
    n = act.switch_count
    h.keep = True
    h.step(1.0)
    assert all(int(r["m1"]["flags"]) & int(Flag.EXHAUST_OPEN) for r in h.records)
    assert act.exhaust_open and not act.inflate_open and act.switch_count == n  # no chatter
    assert h.sim.plant("m1").pressure_bar < 0.05


def test_a_vent_estop_opens_the_exhaust_at_once(harness: Any) -> None:
    h = onoff_rig(harness, 30.0, safety={"estop_action": "vent"})
    assert h.cmd("setpoint", muscle="m1", bar=3.0)["ok"]
    h.step(2.0)
    assert h.cmd("estop", reason="test")["ok"]
    h.step(0.01)
    assert h.state == "ESTOP" and h.m1.actuation.exhaust_open
    assert not h.m1.actuation.inflate_open
    h.step(2.0)
    assert h.sim.plant("m1").pressure_bar < 0.05


def test_the_safe_pressure_is_held_by_pwm_in_a_fault(harness: Any) -> None:
    """80 kg needs pressure: a length sensor dying faults the rig, and the valves keep
    the safe pressure (PWM), neither venting nor running away."""
    h = onoff_rig(harness, 80.0, initial_bar=3.0,
                  faults=[{"at_s": 1.0, "muscle": "m1", "signal": "length", "kind": "dead"}])
    h.step(4.0)
    assert h.ctrl.supervisor.state == State.FAULT
    safe = h.m1.safe_pressure_bar
    assert safe > 0.5
    assert h.sim.plant("m1").pressure_bar == pytest.approx(safe, abs=0.1)


@pytest.mark.parametrize("at_bar", [3.0])
def test_a_stuck_valve_ends_in_the_tracking_fault_and_the_safe_state(
        harness: Any, at_bar: float) -> None:
    h = onoff_rig(harness, 30.0, faults=[{"at_s": 0.5, "muscle": "m1", "signal": "valve",
                                          "kind": "stuck"}])
    h.step(0.6)  # both valves stuck shut: the pressure stays at 0
    assert h.cmd("setpoint", muscle="m1", bar=at_bar)["ok"]
    h.step(4.0)
    sup = h.ctrl.supervisor
    assert sup.state == State.FAULT
    assert any("follow" in f or "track" in f for f in sup.faults), sup.faults


@pytest.mark.parametrize("step_mm", [-5.0, 5.0])
def test_a_stuck_valve_in_position_mode_ends_in_a_fault_and_the_safe_state(
        harness: Any, step_mm: float) -> None:
    """In mode position the command is the measured pressure, so the pressure tracking
    check cannot see a valve that does not act: the actuation's own check does (a valve
    open for a while without the pressure moving its way)."""
    h = onoff_rig(harness, 30.0, initial_bar=3.0)
    h.step(1.0)
    assert h.cmd("mode", muscle="m1", mode="position", feedforward=False)["ok"]
    h.step(0.5)
    h.sim.inject_fault("m1", "valve", "stuck")  # both valves shut, whatever is asked
    length = h.sim.plant("m1").length_mm
    assert h.cmd("setpoint", muscle="m1", length_mm=length + step_mm, ramp_s=1.0)["ok"]
    h.step(4.0)
    sup = h.ctrl.supervisor
    assert sup.state == State.FAULT, sup.faults
    valve = "exhaust" if step_mm > 0 else "inflate"  # longer: vent; shorter: fill
    assert any(f"does not follow the {valve} valve" in f for f in sup.faults), sup.faults


def test_positioning_without_a_fault_raises_no_valve_alarm(harness: Any) -> None:
    h = onoff_rig(harness, 30.0, initial_bar=3.0)
    h.step(1.0)
    assert h.cmd("mode", muscle="m1", mode="position", feedforward=False)["ok"]
    for step_mm in (-8.0, 8.0, -3.0):
        length = h.sim.plant("m1").length_mm
        assert h.cmd("setpoint", muscle="m1", length_mm=length + step_mm, ramp_s=1.0)["ok"]
        h.step(4.0)
    assert h.ctrl.supervisor.state != State.FAULT, h.ctrl.supervisor.faults
