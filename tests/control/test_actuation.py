"""The actuation seam: today's regulator + exhaust behind the `Actuation` Protocol."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from pamd.config import load_config
from pamd.loop.control.actuation import Actuation, RegulatorActuation
from pamd.wire.errors import ConfigError
from pamd.wire.tick import Flag, MuscleTick

REPO = Path(__file__).resolve().parents[2]


def write(act: Actuation, command_bar: float, pressure_bar: float, vent: bool,
          h: Any) -> int:
    """One tick of the actuation stage (`Actuation.update`): the flag bits it sets."""
    t = MuscleTick()
    t.command_bar, t.valve_pressure_bar, t.vent = command_bar, pressure_bar, vent
    act.update(t, h.t, h.period_s)
    return t.flags


def test_the_regulator_actuation_writes_the_setpoint_and_vents_on_request(
        harness: Any) -> None:
    h = harness()
    h.step(0.01)
    act: Actuation = h.m1.actuation
    assert isinstance(act, RegulatorActuation)
    reg = h.sim.plant("m1").regulator
    assert write(act, 2.0, 0.0, False, h) == 0
    assert reg.setpoint_bar == pytest.approx(2.0) and not reg.exhaust_open
    assert write(act, 0.0, 0.0, True, h) == int(Flag.EXHAUST_OPEN)
    assert reg.exhaust_open and act.exhaust_open and act.switch_count == 1
    write(act, 0.0, 0.0, True, h)  # stays open: no new switch
    write(act, 1.0, 0.0, False, h)
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


def test_the_exhaust_assist_opens_below_its_threshold_with_hysteresis(harness: Any) -> None:
    h = harness()
    h.step(0.01)
    act = h.m1.actuation
    valve, exhaust = act.valve, act.exhaust
    assisted = RegulatorActuation(valve, exhaust, assist_below_bar=2.0)
    reg = h.sim.plant("m1").regulator
    assert write(assisted, 1.0, 1.05, False, h) == 0  # 0.05 bar above: shut
    assert write(assisted, 1.0, 1.2, False, h) == int(Flag.EXHAUST_OPEN)
    assert reg.exhaust_open and assisted.switch_count == 1
    assert write(assisted, 1.0, 1.05, False, h)  # within the hysteresis: open
    assert write(assisted, 1.0, 1.02, False, h) == 0  # within 0.03: shut
    assert not reg.exhaust_open and assisted.switch_count == 2
    assert write(assisted, 2.5, 3.5, False, h) == 0  # above the threshold
    assert write(assisted, 1.0, float("nan"), False, h) == 0  # untrusted: shut
    # without an assist (the default) the same gap never opens the exhaust valve
    assert write(act, 1.0, 1.5, False, h) == 0 and not reg.exhaust_open


def _refusal(tmp_path: Path, config: str, edits: list[tuple[str, str]]) -> str:
    """The ConfigError of config/`config` with its `edits` (old, new) made; it must name
    the file and the line of the exhaust assist key."""
    bad = (REPO / "config" / config).read_text()
    for old, new in edits:
        bad = bad.replace(old, new, 1)
    path = tmp_path / "bad.yaml"
    path.write_text(bad)
    with pytest.raises(ConfigError) as err:
        load_config(str(path))
    line = bad.splitlines().index("    exhaust_assist_below_bar: 2.0") + 1
    assert f"bad.yaml:{line}" in str(err.value)
    return str(err.value)


def test_an_exhaust_assist_needs_an_exhaust_valve(tmp_path: Path) -> None:
    err = _refusal(tmp_path, "sim.yaml", [
        ("      exhaust:  {driver: sim, channel: m1.exhaust}\n", ""),
        ("\n    load_kg: 30 ", "\n    exhaust_assist_below_bar: 2.0\n    load_kg: 30 ")])
    assert "muscles[0].exhaust_assist_below_bar" in err and "signals.exhaust" in err


def test_on_off_valves_take_no_exhaust_assist(tmp_path: Path) -> None:
    err = _refusal(tmp_path, "sim-onoff.yaml", [
        ("\n    actuation: onoff", "\n    actuation: onoff\n    exhaust_assist_below_bar: 2.0")])
    assert "no exhaust assist with actuation: onoff" in err
