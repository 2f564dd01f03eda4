"""After the safety chain opened nothing moves until an operator's reset (issue 37
item 1), whatever the trust state of the pressure sensor: the held command never
rises on its own, and when the chain closes (the air back) the pressure does not
refill the muscle, nor does the length move beyond what leakage does.

Before: at 30 kg in a 2 Hz 1-5 bar sine at 30 bar/s, the chain opening held the
command at 4.53 bar over a pressure that settled at 3.23 bar; the tracking check,
still running with the air cut, distrusted the pressure after 1 s, so the step that
lowers the hold when the air returns (trusted pressures only) never came: the
closing chain refilled the muscle to 4.52 bar, still in ESTOP."""

from __future__ import annotations

from collections.abc import Callable

from tests.safety.conftest import SafetyRig
from tests.safety.test_chain import CHAIN

#: what the regulator's hysteresis (the sim's backlash: 20 mbar wide) lets through
HYSTERESIS_BAR = 0.02
#: a length change that is no motion (the sim's DMSP-20 at 30 kg: ~8 mm/bar)
STILL_MM = 0.05


def _after_return(rig: SafetyRig, close_at_s: float) -> tuple[float, float]:
    """Run to just before the chain closes, then 2 s on: (pressure, length) before."""
    rig.run_until(close_at_s - 0.01)
    p0, len0 = rig.plant.pressure_bar, rig.plant.length_mm
    rig.run_until(close_at_s + 2.0)
    return p0, len0


def test_the_chain_closing_in_estop_refills_nothing(
        safety_rig: Callable[..., SafetyRig]) -> None:
    """The issue's case: config/sim-chain.yaml's chain at 30 kg from 3 bar, slew 30
    bar/s, no relay on the heartbeat, a 2 Hz 1-5 bar sine; the chain opens at 3.05 s
    (the pressure lags its command by ~0.6 bar) and closes at 6 s."""
    rig = safety_rig(30.0, 3.0, [
        {"at_s": 3.05, "signal": "safety_chain", "kind": "open"},
        {"at_s": 6.0, "signal": "safety_chain", "kind": "closed"}],
        safety_chain=CHAIN, control={"slew_limit_bar_per_s": 30.0})
    h, m, plant = rig.h, rig.m, rig.plant
    h.keep = True
    rig.run(0.01)
    assert h.cmd("profile", kind="sine", min_bar=1.0, max_bar=5.0, freq_hz=2.0)["ok"]
    rig.run_until(3.05)
    at_open = m.valve_cmd_bar
    assert at_open - plant.pressure_bar > 0.3  # the command ahead of its air
    p0, len0 = _after_return(rig, 6.0)
    assert h.state == "ESTOP" and h.records[-1]["safety_chain"] == 1.0
    assert m.inputs.pressure_ok  # no tracking finding while the air was cut
    assert abs(plant.pressure_bar - p0) < HYSTERESIS_BAR, (p0, plant.pressure_bar)
    assert abs(plant.length_mm - len0) < STILL_MM, (len0, plant.length_mm)
    held = [k.cmd for k in rig.ticks if k.t_s > 3.05]
    assert all(b <= a + 1e-12 for a, b in zip(held, held[1:], strict=False))  # never up
    assert held[-1] < at_open - 1.0  # down with the pressure, not at the command
    rig.check_invariants()


def test_a_supply_lost_in_a_ramp_then_an_estop_refills_nothing(
        safety_rig: Callable[..., SafetyRig]) -> None:
    """The issue's variant: the muscle's own supply lost in a ramp (no supply input
    sees it), the tracking check rightly distrusts the pressure (FAULT), an e-stop
    pressed and released brings the air back with the pressure still untrusted. The
    force and length say the reading is right (the air did not follow): the hold
    takes it, not the command that ran 1.9 bar ahead."""
    rig = safety_rig(30.0, 3.0, [
        {"at_s": 1.0, "muscle": "m1", "signal": "supply", "kind": "lost"},
        {"at_s": 2.1, "signal": "safety_chain", "kind": "open"},
        {"at_s": 4.0, "signal": "safety_chain", "kind": "closed"}],
        safety_chain={"estop": CHAIN["estop"]})
    h, m, plant = rig.h, rig.m, rig.plant
    h.keep = True
    rig.run(0.5)
    assert h.cmd("profile", kind="ramp", to_bar=6.0, rate_bar_per_s=2.0)["ok"]
    rig.run_until(2.1)
    assert h.state == "FAULT" and not m.inputs.pressure_ok
    assert m.valve_cmd_bar - plant.pressure_bar > 1.5
    p0, len0 = _after_return(rig, 4.0)
    assert h.state == "ESTOP" and not m.inputs.pressure_ok
    assert abs(plant.pressure_bar - p0) < HYSTERESIS_BAR, (p0, plant.pressure_bar)
    assert abs(plant.length_mm - len0) < STILL_MM, (len0, plant.length_mm)
    rig.check_invariants(actuator_works=False)


def test_a_pressure_sensor_dying_while_the_air_is_cut_refills_nothing(
        safety_rig: Callable[..., SafetyRig]) -> None:
    """The pressure sensor dies (reads 0) while the chain is open: the hold stays at the
    last pressure trusted, not at the dead reading (that would vent the muscle when
    the air returns) nor back at the command."""
    rig = safety_rig(30.0, 3.0, [
        {"at_s": 1.0, "signal": "safety_chain", "kind": "open"},
        {"at_s": 1.5, "muscle": "m1", "signal": "pressure", "kind": "dead"},
        {"at_s": 2.5, "signal": "safety_chain", "kind": "closed"}],
        safety_chain=CHAIN, control={"slew_limit_bar_per_s": 30.0})
    h, m, plant = rig.h, rig.m, rig.plant
    h.keep = True
    rig.run(0.01)
    assert h.cmd("profile", kind="sine", min_bar=1.0, max_bar=5.0, freq_hz=2.0)["ok"]
    rig.run_until(1.6)
    assert h.state == "ESTOP" and not m.inputs.pressure_ok
    p0, len0 = _after_return(rig, 2.5)
    assert abs(plant.pressure_bar - p0) < HYSTERESIS_BAR, (p0, plant.pressure_bar)
    assert abs(plant.length_mm - len0) < STILL_MM, (len0, plant.length_mm)
    rig.check_invariants()
