"""The reproductions of issue 11's "Why", each as a regression test on the virtual
clock: a length encoder dying in the safe state at 80 kg, start-up with 80 kg
hanging from a vented muscle, a `home` that lies, and a profile a limit holds
back while the summary looked fine."""

from __future__ import annotations

from collections.abc import Callable

import pytest

from .conftest import SafetyRig


@pytest.mark.parametrize("plausibility", [True, False], ids=["checked", "limiter-alone"])
def test_encoder_dying_in_the_safe_state_at_80kg_never_walks_the_command_down(
        safety_rig: Callable[..., SafetyRig], plausibility: bool) -> None:
    # Before: the contraction soft limit, still running in FAULT, read the dead
    # encoder's 0 mm as 100 % contraction and walked the command from the 1.58 bar
    # safe pressure to 0 bar; the muscle over-stretched and the stop never completed.
    rig = safety_rig(80.0, 3.0, [{"at_s": 1.5, "muscle": "m1", "signal": "length",
                                  "kind": "dead"}],
                     safety={"plausibility": {"enabled": plausibility}})
    rig.run(0.5)
    rig.cmd("stop")
    rig.run(4.5)  # the stop reaches 1.58 bar in 0.3 s; the encoder dies 1 s later
    m = rig.m
    assert m.safe_pressure_bar == pytest.approx(1.58, abs=0.01)
    rig.check_invariants()
    assert rig.min_safe_command() == pytest.approx(m.safe_pressure_bar)
    assert rig.h.ctrl.at_safe_state()  # the stop completes and stays complete
    assert rig.plant.contraction > -0.04  # inside the pretension limit
    if plausibility:  # ... and the dead encoder is a fault naming it, found at once
        assert rig.h.state == "FAULT"
        assert "m1.length reads 0.00 mm" in rig.h.ctrl.supervisor.fault_reason
        found = [e for e in rig.h.sink.events if e[1] == "implausible"]
        assert found and found[0][0] == pytest.approx(1.5, abs=0.002)
        assert "length" not in found[0][2]["trusted"]


def test_startup_with_80kg_on_a_vented_muscle_ramps_to_the_safe_pressure_and_says_so(
        safety_rig: Callable[..., SafetyRig]) -> None:
    # Before: the pretension guard copied the PID-augmented command into the setpoint
    # each time it re-engaged: the valve reached 6 bar in 88 ticks, lifted the 80 kg
    # 35 mm, and held 6 bar with the integral pinned while the status said "holding
    # measured pressure (0.00 bar)".
    rig = safety_rig(80.0, 0.0)
    x0 = rig.plant.contraction
    assert x0 < -0.04  # 4.4 % stretched: outside the pretension limit
    rig.run(5.0)
    m = rig.m
    rig.check_invariants()
    reason = rig.h.ctrl.supervisor.history[0].reason
    assert "stretched 4.4 %" in reason and "ramping from 0.00 bar" in reason
    assert f"safe pressure {m.safe_pressure_bar:.2f} bar" in reason
    assert "holding measured pressure" not in reason
    start = [e for e in rig.h.sink.events if e[1] == "startup"]
    assert start[0][2]["action"] == "safe_ramp" and "stretched" in start[0][2]["reason"]
    cmds = [k.cmd for k in rig.ticks]
    assert max(cmds) < m.safe_pressure_bar + 0.1  # never ratcheted up (was 6 bar)
    safe = m.safe_pressure_bar
    assert max(k.sp for k in rig.ticks) <= safe + 1e-9  # the setpoint: the ramp only
    assert m.valve_cmd_bar == pytest.approx(safe) and m.setpoint_bar == pytest.approx(safe)
    assert abs(m.pressure_loop.pid.i) < 0.05  # not pinned
    lifted_mm = (rig.plant.contraction - x0) * 200.0
    assert 0.0 < lifted_mm < 5.0  # back inside the limit, not lifted 35 mm
    assert rig.plant.contraction > -0.04
    assert rig.h.state == "IDLE" and rig.h.ctrl.at_safe_state()


def test_a_length_mode_is_refused_during_the_safe_ramp_and_taken_after_a_setpoint(
        safety_rig: Callable[..., SafetyRig]) -> None:
    # Before: `mode position` during the start-up's safe ramp (80 kg, vented) was
    # answered ok and dropped on the next tick, since the safe ramp leaves length modes.
    rig = safety_rig(80.0, 0.0)
    rig.run(0.1)  # the ramp to 1.58 bar at 5 bar/s takes 0.32 s
    assert rig.m.in_safe_ramp and rig.m.setpoint_bar < rig.m.safe_pressure_bar
    v = rig.h.cmd("mode", muscle="m1", mode="position", feedforward=False)
    assert not v["ok"] and "ramping to its safe pressure" in v["error"], v
    assert "send a setpoint" in v["error"]
    rig.cmd("setpoint", muscle="m1", bar=rig.m.safe_pressure_bar + 0.3)
    rig.run(1.0)
    assert not rig.m.in_safe_ramp
    rig.cmd("mode", muscle="m1", mode="position", feedforward=False)
    rig.run(0.5)
    assert rig.m.in_length_mode  # taken, and kept
    rig.check_invariants()


def test_a_length_mode_takes_over_from_a_completed_safe_ramp(
        safety_rig: Callable[..., SafetyRig]) -> None:
    # issue 38: once the ramp holds the safe pressure, a length mode takes over from it
    # (as a setpoint would) and is kept, instead of being refused
    rig = safety_rig(80.0, 0.0)
    rig.run(1.0)
    m = rig.m
    assert m.in_safe_ramp and m.setpoint_bar == pytest.approx(m.safe_pressure_bar)
    rig.cmd("mode", muscle="m1", mode="position", feedforward=False)
    rig.run(0.5)
    assert m.in_length_mode and not m.in_safe_ramp  # taken, and kept
    assert abs(m.setpoint_bar - m.safe_pressure_bar) < 0.1  # bumpless
    rig.check_invariants()


def test_startup_inside_the_limits_holds_the_measured_pressure(
        safety_rig: Callable[..., SafetyRig]) -> None:
    rig = safety_rig(80.0, 3.0)
    rig.run(1.0)
    reason = rig.h.ctrl.supervisor.history[0].reason
    assert reason.startswith("sensors read; holding measured pressure (m1 3.00 bar)")
    assert not rig.m.in_safe_ramp
    assert all(abs(k.cmd - 3.0) < 0.02 for k in rig.ticks)


def test_startup_above_the_pressure_limit_comes_down_at_the_slew_limit(
        safety_rig: Callable[..., SafetyRig]) -> None:
    # a regulator holding 5 bar across a restart, with the limit now 4 bar
    rig = safety_rig(30.0, 5.0, muscles=[{**_muscle(30.0), "limits": {"max_pressure_bar": 4.0}}])
    rig.run(2.0)
    assert "pressure 5.00 bar above the limit 4 bar" in rig.h.ctrl.supervisor.history[0].reason
    cmds = [k.cmd for k in rig.ticks]
    steps = [b - a for a, b in zip(cmds, cmds[1:], strict=False)]
    slew = rig.m.envelope.slew_limit_bar_per_s
    assert min(steps) >= -slew * rig.h.period_s - 1e-9  # no jump down
    assert rig.m.valve_cmd_bar == 0.0  # 30 kg: the safe pressure is 0


def _muscle(load_kg: float) -> dict[str, object]:
    sig: dict[str, object] = {k: {"driver": "sim", "channel": f"m1.{k}"}
                              for k in ("pressure", "force", "length")}
    sig["valve"] = {"driver": "sim", "channel": "m1.valve", "raw_min": 0.0, "raw_max": 6.0}
    sig["exhaust"] = {"driver": "sim", "channel": "m1.exhaust"}
    return {"name": "m1", "type": "dmsp20", "load_kg": load_kg, "signals": sig}


def test_a_profile_held_at_a_soft_limit_shows_in_tracking_an_event_and_the_summary(
        safety_rig: Callable[..., SafetyRig]) -> None:
    # Before: the guard clamped the setpoint too, so a profile the contraction limit
    # held back looked well tracked. Now the setpoint stays the profile's target.
    rig = safety_rig(15.0, 0.0, muscles=[{**_muscle(15.0),
                                          "limits": {"max_contraction": 0.15}}])
    rig.run(0.01)
    rig.cmd("profile", kind="constant", to_bar=5.0, duration_s=6.0)
    rig.run(6.0)
    m = rig.m
    assert rig.h.state == "RUNNING"
    assert m.setpoint_bar == pytest.approx(5.0)  # the target, never clamped
    assert m.valve_cmd_bar < 4.0  # the guard holds the command back
    rig.check_invariants()
    assert max(k.contraction_true for k in rig.ticks) < 0.16
    track = rig.h.sink.tracking()["m1"]
    assert track["max_error_bar"] > 1.0  # honest: the profile was not followed
    assert track["soft_limit_s"] > 2.0 and track["soft_limit_events"] == 1
    ev = [e for e in rig.h.sink.events if e[1] == "soft_limit"]
    assert len(ev) == 1 and ev[0][2]["limit"] == "contraction"
    assert "held at the contraction limit" in ev[0][2]["reason"]


def test_pid_integral_moves_away_from_a_clamp_never_into_it() -> None:
    from pamd.loop.control.pid import Pid

    pid = Pid(0.3, 20.0, 0.0, 30.0, 1.0, 1.5)
    pid.reset(0.0, 0.5)
    pid.step(-0.2, 0.0, 0.001)  # wants less: the integral falls
    pid.keep_integral_off_clamp(0.5, clamped_down=True)
    assert pid.i < 0.5  # away from an upper clamp: allowed
    pid.reset(0.0, 0.5)
    pid.step(0.2, 0.0, 0.001)  # wants more against a clamp that lowered the command
    pid.keep_integral_off_clamp(0.5, clamped_down=True)
    assert pid.i == 0.5  # into the clamp: not wound up
    pid.reset(0.0, 0.5)
    pid.step(-0.2, 0.0, 0.001)  # wants less against a floor (a guard raised it)
    pid.keep_integral_off_clamp(0.5, clamped_down=False)
    assert pid.i == 0.5
    pid.reset(0.0, 0.5)
    pid.step(0.2, 0.0, 0.001)
    pid.keep_integral_off_clamp(0.5, clamped_down=False)
    assert pid.i > 0.5


LAG_PLANT = {"drivers": [{"name": "sim", "type": "sim", "options": {
    "seed": 1, "muscles": [{"name": "m1", "load_kg": 30.0, "pneumatics": "lag"}]}}]}


def test_a_profile_reaching_the_pressure_limit_is_not_held_back(harness) -> None:
    """The seeds' 0-6 bar sine touches the 6 bar limit: only the PID's correction is
    trimmed there, the setpoint is followed, so the summary reports no time held back
    (the first `pamd run --profile sine` said "held back for 0.5 s"). On the 'lag'
    plant, whose pressure reaches 0 bar at the sine's bottom: on the 'flow' plant the
    bottom is test_a_negative_pid_correction_at_0_bar_is_not_a_pretension_guard."""
    h = harness(**LAG_PLANT)
    h.step(0.01)
    h.cmd("profile", kind="sine", cycles=1)
    trimmed = 0
    while h.state == "RUNNING":  # lead-in and one 20 s cycle
        h.step(0.01)
        trimmed += h.m1.valve_cmd_bar >= h.m1.envelope.max_pressure_bar - 1e-9
    assert h.t > 20.0 and trimmed > 0  # the command did reach the limit
    assert h.sink.tracking()["m1"]["soft_limit_s"] == 0.0
    assert not [e for e in h.sink.events if e[1] == "soft_limit"]


def test_a_negative_pid_correction_at_0_bar_is_not_a_pretension_guard(harness) -> None:
    """At the sine's 0 bar bottom the regulator vents the last mbar slowly and the PID's
    correction is negative: the limiter keeps the command at 0 without naming a guard
    (the guards' bounds are +-inf when none holds), so nothing counts as held back."""
    h = harness()
    h.step(0.01)
    h.cmd("profile", kind="sine", cycles=1)
    while h.state == "RUNNING":
        h.step(0.01)
    assert h.sink.tracking()["m1"]["soft_limit_s"] == 0.0
