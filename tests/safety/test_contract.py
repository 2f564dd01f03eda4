"""The safety contract (issue 11): for every scripted fault kind x load (0, 30, 80 kg)
x the state the rig is in when it strikes (IDLE, RUNNING, HOLD, a safe ramp,
start-up, and an ESTOP ramp), on the virtual clock, the invariants hold over the whole run: the
command never above the limits, in a safe state never below the safe pressure and
never faster than the slew limit, the setpoint never pushed by a guard, and the
muscle inside its hard contraction limits where the physics allows.

The same contract holds for a muscle on on/off valves (PWM from the command, the
exhaust opened to vent; issue #14), at 30 kg only to keep the run time reasonable:
every fault kind x every state.

This suite is what later redesigns must keep green. Each run is a few virtual
seconds (a few thousand ticks)."""

from __future__ import annotations

from typing import Any

import pytest

from .conftest import RigMaker, SafetyRig, from_a_copy

SENSOR_FAULTS = [(s, k) for s in ("length", "force", "pressure")
                 for k in ("dead", "stuck", "noisy", "jump", "silent")]
FAULTS = SENSOR_FAULTS + [("supply", "lost"), ("valve", "stuck"), ("driver", "error")]
LOADS = (0.0, 30.0, 80.0)
STATES = ("idle", "running", "hold", "safe_ramp", "startup", "estop")
#: When the fault strikes in each scenario, s after the driver opened.
FAULT_AT_S = {"idle": 0.5, "running": 1.0, "hold": 1.5, "safe_ramp": 2.1, "startup": 0.0,
              "estop": 1.05}
AFTER_S = 2.5  # how long the run goes on after the fault


def _pressures(load_kg: float) -> tuple[float, float, float]:
    """(power-up pressure, profile low, profile high) inside the limits for the load."""
    return (3.0, 2.0, 5.0) if load_kg >= 50.0 else (0.0, 1.0, 4.0)


def _to_the_fault(rig: SafetyRig, state: str, load_kg: float) -> None:
    """Bring the rig to `state`, up to the tick at which the fault strikes
    (FAULT_AT_S[state]); the run then goes on for AFTER_S."""
    _, low, high = _pressures(load_kg)
    if state == "startup":
        return
    rig.run(0.01)
    if state == "idle":
        rig.run_until(FAULT_AT_S["idle"])
    elif state in ("running", "hold", "estop"):
        rig.cmd("profile", kind="sine", min_bar=low, max_bar=high, freq_hz=0.25)
        rig.run_until(1.0)
        if state == "hold":
            rig.cmd("hold")
        elif state == "estop":  # the emergency ramp (20 bar/s) is under way
            rig.cmd("estop", reason="contract suite")
        rig.run_until(FAULT_AT_S[state])
    else:  # a safe ramp down from a high pressure: a stop
        rig.cmd("setpoint", muscle="m1", bar=4.5)
        rig.run_until(2.0)
        rig.cmd("stop")
        assert rig.m.in_safe_ramp
        rig.run_until(FAULT_AT_S["safe_ramp"])


def _fault(signal: str, kind: str, state: str) -> dict[str, Any]:
    return {"at_s": FAULT_AT_S[state], "signal": signal, "failure": kind,
            "muscle": "*" if signal == "driver" else "m1"}


def _initial_bar(state: str, load_kg: float) -> float:
    return 0.0 if state == "startup" else _pressures(load_kg)[0]


def _fresh(safety_rig: RigMaker, signal: str, kind: str, actuation: str,
           load_kg: float, state: str) -> SafetyRig:
    """A rig built with the fault in its schedule, run to the fault and AFTER_S on."""
    rig = safety_rig(load_kg, _initial_bar(state, load_kg), [_fault(signal, kind, state)],
                     actuation)
    _to_the_fault(rig, state, load_kg)
    rig.run(AFTER_S)
    return rig


def _from_a_copy(safety_rig: RigMaker, signal: str, kind: str, actuation: str,
                 load_kg: float, state: str) -> SafetyRig:
    """As `_fresh`, from a copy of the scenario's rig at the fault time."""
    rig = from_a_copy(
        safety_rig, ("contract", actuation, load_kg, state),
        lambda: safety_rig(load_kg, _initial_bar(state, load_kg), [], actuation),
        lambda r: _to_the_fault(r, state, load_kg), _fault(signal, kind, state))
    rig.run(AFTER_S)
    return rig


#: (actuation, load): the regulator at every load, on/off valves at 30 kg.
RIGS = [("proportional", load) for load in LOADS] + [("onoff", 30.0)]


@pytest.mark.parametrize("state", STATES)
@pytest.mark.parametrize("actuation, load_kg", RIGS, ids=[f"{a}-{w:g}kg" for a, w in RIGS])
@pytest.mark.parametrize("signal, kind", FAULTS, ids=[f"{s}-{k}" for s, k in FAULTS])
def test_the_invariants_hold_whatever_fails(safety_rig: RigMaker, signal: str,
                                             kind: str, actuation: str, load_kg: float,
                                             state: str) -> None:
    if state == "startup":  # the fault is there from the start: nothing to share
        rig = _fresh(safety_rig, signal, kind, actuation, load_kg, state)
    else:
        rig = _from_a_copy(safety_rig, signal, kind, actuation, load_kg, state)
    actuator_works = signal not in ("supply", "valve", "driver")
    rig.check_invariants(actuator_works)


@pytest.mark.parametrize("state", [s for s in STATES if s != "startup"])
def test_a_copy_at_the_fault_time_runs_exactly_as_a_fresh_rig(
        safety_rig: RigMaker, state: str) -> None:
    """The copies above are the fresh runs, tick for tick: a sensor fault (noise, drawn
    from the fault's own random numbers) on the regulator and one of the device on the
    on/off valves, each struck in every state."""
    for signal, kind, actuation in (("force", "noisy", "proportional"),
                                    ("driver", "error", "onoff")):
        fresh = _fresh(safety_rig, signal, kind, actuation, 30.0, state)
        copied = _from_a_copy(safety_rig, signal, kind, actuation, 30.0, state)
        assert len(copied.ticks) == len(fresh.ticks) > 2000
        assert copied.ticks == fresh.ticks
        for rig in (fresh, copied):  # the fault did strike
            assert rig.h.sim.sensor_faults.any or rig.h.sim.fault is not None

