"""Issue 23 item 5: every fault entry is safe, whichever signal failed and whatever
runs. The tick that finds the fault is held to the safe state's invariants (the
contract's `check_invariants` counts it since issue 23): the command never falls
below min(safe pressure, the command at entry) and never moves faster than the safe
slew, including when the pressure itself became untrusted (the loop opens: the
command used to jump from the PID's output to the setpoint). The reproductions of
the issue's figures at 80 kg (safe pressure 1.58 bar), on the virtual clock.

The coordinated entry (`RigController.pace_safe_entry`) and the on/off valves' floor
are here too; the tuning run and collections are in test_fault_paths.py."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from pamd.config import LoadedConfig
from pamd.loop.control.feedforward import LoadedModel
from pamd.loop.harness import Harness
from pamd.wire.tick import State
from tests.experiment.test_sequencer import start

from ..conftest import sim_dict
from .conftest import SafetyRig, sim_driver


def entry(rig: SafetyRig) -> tuple[Any, Any]:
    """(the last tick before the fault's entry, the entry tick)."""
    for a, b in zip(rig.ticks, rig.ticks[1:], strict=False):
        if not a.safe and b.safe:
            return a, b
    raise AssertionError("no safe-state entry in the run")


def assert_safe_entry(rig: SafetyRig) -> None:
    """The whole run's contract, and from the entry on: never below min(safe pressure,
    the command at entry), never faster than the safe slew."""
    rig.check_invariants()
    before, first = entry(rig)
    m = rig.m
    step = m.envelope.safe_slew_bar_per_s * rig.h.period_s
    assert abs(first.cmd - before.cmd) <= step + 1e-9
    floor = min(m.safe_pressure_bar, before.cmd)
    after = [k for k in rig.ticks if k.t_s >= first.t_s]
    assert min(k.cmd for k in after) >= floor - 1e-9


def test_a_pressure_sensor_reading_low_then_silent_enters_without_a_step(
        safety_rig: Callable[..., SafetyRig]) -> None:
    # Before: 1.277 -> 1.000 bar in the first FAULT tick (-0.277 bar in 1 ms, 55x the
    # slew limit): the stale pressure opened the loop and the command became the setpoint.
    rig = safety_rig(80.0, 3.0, [
        {"at_s": 1.0, "muscle": "m1", "signal": "pressure", "kind": "jump", "size": -0.28},
        {"at_s": 2.0, "muscle": "m1", "signal": "pressure", "kind": "silent"}])
    rig.run(0.01)
    rig.cmd("setpoint", muscle="m1", bar=1.0)
    rig.run(3.5)
    assert rig.h.state == "FAULT" and "m1.pressure" in rig.h.ctrl.supervisor.fault_reason
    before, _ = entry(rig)
    assert before.cmd - before.sp > 0.2  # the PID held the command above the setpoint
    assert before.cmd < rig.m.safe_pressure_bar  # ... and under the safe pressure
    assert_safe_entry(rig)
    assert rig.h.ctrl.at_safe_state()  # then up to the safe pressure, at the slew limit


def test_a_noisy_pressure_sensor_enters_without_a_step(
        safety_rig: Callable[..., SafetyRig]) -> None:
    # Before: +0.945 bar in one tick when the jump check distrusted the pressure
    rig = safety_rig(80.0, 3.0, [{"at_s": 1.5, "muscle": "m1", "signal": "pressure",
                                  "kind": "noisy", "size": 0.3}])
    rig.run(0.01)
    rig.cmd("profile", kind="sine", min_bar=2.0, max_bar=5.0, freq_hz=0.25)
    rig.run(3.0)
    assert "m1.pressure jumped" in rig.h.ctrl.supervisor.fault_reason
    assert_safe_entry(rig)


def test_a_fault_found_by_the_tracking_check_shapes_the_tick_that_finds_it(
        safety_rig: Callable[..., SafetyRig]) -> None:
    """The measured pressure must follow the last command: judged before this tick's
    command is made, so the tick that finds a stuck valve is already the safe entry."""
    rig = safety_rig(80.0, 3.0, [{"at_s": 1.0, "muscle": "m1", "signal": "valve",
                                  "kind": "stuck"}])
    rig.run(0.01)
    rig.cmd("profile", kind="sine", min_bar=2.0, max_bar=5.0, freq_hz=0.25)
    rig.run(4.0)
    assert "does not follow the command" in rig.h.ctrl.supervisor.fault_reason
    rig.check_invariants(actuator_works=False)
    before, first = entry(rig)
    assert abs(first.cmd - before.cmd) <= rig.m.envelope.safe_slew_bar_per_s * 0.001 + 1e-9


def test_a_fault_during_a_load_change_enters_without_a_step(
        safety_rig: Callable[..., SafetyRig]) -> None:
    # Before: +0.315 bar in one tick during LOAD_CHANGE
    rig = safety_rig(30.0, 2.0, [{"at_s": 1.0, "muscle": "m1", "signal": "pressure",
                                  "kind": "silent"}])
    rig.run(0.01)
    plan = ("name: load\nmuscle: m1\nsettle: {seconds: 1}\nsteps:\n"
            "  - {name: heavy, load_kg: 80}\n")
    assert start(rig.h, plan)["ok"]
    rig.run(0.5)
    assert rig.h.state == "LOAD_CHANGE"
    rig.run(2.5)
    assert rig.h.state == "FAULT"
    assert [k for k in rig.ticks if k.state == State.LOAD_CHANGE]
    assert_safe_entry(rig)


def test_a_fault_with_adaptation_on_enters_without_a_step(
        sim_config: Callable[..., LoadedConfig], static_model: Path) -> None:
    # Before: -0.22 bar in one tick with the model's online adaptation on
    muscle = {"name": "m1", "load_kg": 30.0, "initial_pressure_bar": 2.0}
    faults = [{"at_s": 2.0, "muscle": "m1", "signal": "pressure", "kind": "noisy",
               "size": 0.3}]
    cfg = sim_config(30.0, drivers=[{"name": "sim", "type": "sim", "options": {
        "seed": 1, "faults": faults, "muscles": [muscle]}}],
        muscles=[{**sim_dict(30.0)["muscles"][0], "adapt": {"enabled": True}}])
    h = Harness(cfg, {"m1": LoadedModel.read(str(static_model), cfg.muscle("m1"),
                                             cfg.limits["m1"])})
    rig = SafetyRig(h)
    try:
        rig.run(0.01)
        rig.cmd("mode", mode="position")
        rig.cmd("profile", kind="sine", min_contraction=0.05, max_contraction=0.15,
                freq_hz=0.25)
        rig.run(3.0)
        assert rig.m.adaptation.enabled
        assert h.state == "FAULT" and "m1.pressure" in h.ctrl.supervisor.fault_reason
        assert [k for k in rig.ticks if k.state == State.RUNNING]
        assert_safe_entry(rig)
    finally:
        h.rig.close()


def test_onoff_valves_hold_the_safe_pressure_with_a_dead_encoder_at_80kg(
        safety_rig: Callable[..., SafetyRig]) -> None:
    # Before: in position mode the measured pressure stayed up to 0.36 bar under the
    # safe pressure for 1.5 s (the PWM's integral, wound up on the ramp down, vented
    # past it). Now the exhaust never opens at or below the safe pressure in FAULT.
    rig = safety_rig(80.0, 3.0, [{"at_s": 2.0, "muscle": "m1", "signal": "length",
                                  "kind": "dead"}], "onoff")
    rig.run(0.01)
    rig.cmd("mode", mode="position", feedforward=False)
    rig.cmd("setpoint", muscle="m1", length_mm=185.0)
    rig.run(4.0)
    m = rig.m
    assert rig.h.state == "FAULT" and "m1.length reads 0.00 mm" in (
        rig.h.ctrl.supervisor.fault_reason)
    fault = [k for k in rig.ticks if k.state == State.FAULT]
    assert fault[0].pressure_true > m.safe_pressure_bar + 1.0  # it came down from above
    assert min(k.pressure_true for k in fault) >= m.safe_pressure_bar
    assert rig.plant.contraction > -m.envelope.max_pretension
    rig.check_invariants()


TWO = [{"name": "m1", "load_kg": 30.0, "initial_pressure_bar": 4.0},
       {"name": "m2", "load_kg": 30.0, "initial_pressure_bar": 1.0}]


def test_the_muscles_of_a_rig_reach_their_safe_state_together(
        sim_config: Callable[..., LoadedConfig]) -> None:
    """The coordinated entry: one ramp duration for every muscle (the longest at its
    own slew limit), so an antagonistic pair does not slam its joint by one muscle
    ramping alone. Here m1 has 4 bar to shed, m2 1 bar: both arrive at 0 bar in the
    0.8 s m1 needs at 5 bar/s, m2 at a quarter of its slew limit."""
    drivers = sim_driver(30.0, 0.0)
    drivers[0]["options"]["muscles"] = TWO
    drivers[0]["options"]["faults"] = [{"at_s": 1.0, "signal": "driver", "kind": "error",
                                        "muscle": "m1"}]
    base = sim_dict(30.0)["muscles"][0]
    muscles = [{**base, "name": n, "signals": {
        k: {**v, "channel": v["channel"].replace("m1.", f"{n}.")}
        for k, v in base["signals"].items()}} for n in ("m1", "m2")]
    h = Harness(sim_config(30.0, drivers=drivers, muscles=muscles))
    try:
        h.step(0.5)
        m1, m2 = h.ctrl.muscles
        assert (round(m1.setpoint_bar, 2), round(m2.setpoint_bar, 2)) == (4.0, 1.0)
        arrived: dict[str, float] = {}
        while h.t < 3.0:
            h.step(h.period_s)
            for m in (m1, m2):
                if h.state == "FAULT" and m.name not in arrived and m.setpoint_bar == 0.0:
                    arrived[m.name] = h.t
        assert h.state == "FAULT" and "driver 'sim'" in h.ctrl.supervisor.fault_reason
        t_fault = h.ctrl.supervisor.history[-1].t_s
        assert arrived["m1"] - t_fault == pytest.approx(0.8, abs=0.005)
        assert arrived["m2"] == pytest.approx(arrived["m1"], abs=0.002)
    finally:
        h.rig.close()


def _pair(sim_config: Callable[..., LoadedConfig], faults: list[dict[str, Any]]) -> Harness:
    """Two muscles, both on a 1-5 bar sine at 0.25 Hz from about 0.9 s (its steepest
    3.1 bar/s), the safe state's slew 1 bar/s: slower than the profile, so a command
    held to the safe state's invariants visibly leaves it."""
    drivers = sim_driver(30.0, 0.0)
    drivers[0]["options"]["muscles"] = [{**m, "initial_pressure_bar": 1.0} for m in TWO]
    drivers[0]["options"]["faults"] = faults
    base = sim_dict(30.0)["muscles"][0]
    muscles = [{**base, "name": n, "signals": {
        k: {**v, "channel": v["channel"].replace("m1.", f"{n}.")}
        for k, v in base["signals"].items()}} for n in ("m1", "m2")]
    h = Harness(sim_config(30.0, drivers=drivers, muscles=muscles,
                           safety={"safe_slew_bar_per_s": 1.0}))
    h.step(0.5)
    verdict = h.cmd("profile", kind="sine", min_bar=1.0, max_bar=5.0, freq_hz=0.25,
                    lead_in_bar_per_s=5.0)
    assert verdict["ok"], verdict
    h.keep = True
    h.step(1.1)  # the jump at 1.1 s: m1's setpoint rising at ~3 bar/s
    return h


def test_a_fault_one_muscle_finds_holds_every_muscles_command_in_that_tick(
        sim_config: Callable[..., LoadedConfig]) -> None:
    """The one change of behaviour of issue 42: the rig decides its safe state once per
    tick, after every muscle's update and before any write, so a fault m2 finds shapes
    m1's write of the same tick: m1's command leaves its profile (held to the safe
    state's slew from its last command) in the tick m2's pressure jumps, not one tick
    later as when each muscle read, computed and wrote in turn."""
    jump = [{"at_s": 1.1, "muscle": "m2", "signal": "pressure", "kind": "jump", "size": 1.0}]
    faulty, clean = _pair(sim_config, jump), _pair(sim_config, [])
    try:
        assert faulty.state == "FAULT" and "m2.pressure" in faulty.ctrl.supervisor.fault_reason
        t_fault = next(tr.t_s for tr in faulty.ctrl.supervisor.history
                       if tr.new == State.FAULT)
        cmd = [r["m1"]["valve_cmd_bar"] for r in faulty.records]
        free = [r["m1"]["valve_cmd_bar"] for r in clean.records]
        t_s = [r["t_s"] for r in faulty.records]
        first = next(k for k, (a, b) in enumerate(zip(cmd, free, strict=True)) if a != b)
        assert t_s[first] == pytest.approx(t_fault)  # the very tick m2 found its fault
        step = 1.0 * faulty.period_s  # the safe slew's step
        assert abs(cmd[first] - cmd[first - 1]) <= step + 1e-9  # held from that tick ...
        # ... off a steeper profile (over 20 ticks: the PID's command is noisy per tick)
        n = 20
        assert abs(cmd[first + n - 1] - cmd[first - 1]) <= n * step + 1e-9
        assert free[first + n - 1] - free[first - 1] > 2.0 * n * step
        assert faulty.records[first]["state"] == State.FAULT
    finally:
        faulty.rig.close()
        clean.rig.close()
