"""The safety contract (test_contract.py's invariants) on config/sim-harsh.yaml's sensors:
quantised, noiseless, filtered, a 10 samples/s load cell, a late pressure, a bursty
encoder. Whatever fails, in whichever state, the command stays within the limits, in
a safe state never below the safe pressure nor faster than the slew limit, and the
muscle inside its hard contraction limits where the physics allows; and no healthy
run before the fault strikes has faulted. At 80 kg (the safe pressure 1.6 bar, the
load off the stops) on the regulator, in the states where the sensors matter most."""

from __future__ import annotations

from typing import Any

import pytest

from .conftest import RigMaker, SafetyRig, from_a_copy

FAULTS = ([(s, k) for s in ("length", "force", "pressure")
           for k in ("dead", "stuck", "noisy", "jump", "silent")]
          + [("supply", "lost"), ("valve", "stuck"), ("driver", "error")])
STATES = ("idle", "running", "safe_ramp")
FAULT_AT_S = {"idle": 0.5, "running": 1.3, "safe_ramp": 2.1}
AFTER_S = 2.5


def _fault(signal: str, kind: str, state: str) -> dict[str, Any]:
    return {"at_s": FAULT_AT_S[state], "signal": signal, "failure": kind,
            "muscle": "*" if signal == "driver" else "m1"}


def _to_the_fault(rig: SafetyRig, state: str) -> None:
    """Bring the rig to `state`, up to the tick at which the fault strikes."""
    rig.run(0.01)
    if state == "idle":
        rig.run_until(FAULT_AT_S["idle"])
    elif state == "running":
        rig.cmd("profile", kind="sine", min_bar=2.0, max_bar=5.0, freq_hz=0.25)
        rig.run_until(FAULT_AT_S["running"])
    else:  # a safe ramp down from a high pressure: a stop
        rig.cmd("setpoint", muscle="m1", bar=4.5)
        rig.run_until(2.0)
        rig.cmd("stop")
        assert rig.m.in_safe_ramp
        rig.run_until(FAULT_AT_S["safe_ramp"])


def _from_a_copy(safety_rig: RigMaker, signal: str, kind: str, state: str) -> SafetyRig:
    """The scenario run to the fault (once per worker: conftest.from_a_copy), the fault
    struck, and AFTER_S on."""
    rig = from_a_copy(safety_rig, ("harsh", state),
                      lambda: safety_rig(80.0, 3.0, [], sensors="harsh"),
                      lambda r: _to_the_fault(r, state), _fault(signal, kind, state))
    rig.run(AFTER_S)
    return rig


@pytest.mark.parametrize("state", STATES)
@pytest.mark.parametrize("signal, kind", FAULTS, ids=[f"{s}-{k}" for s, k in FAULTS])
def test_the_invariants_hold_on_harsh_sensors_whatever_fails(
        safety_rig: RigMaker, signal: str, kind: str, state: str) -> None:
    at_s = FAULT_AT_S[state]
    rig = _from_a_copy(safety_rig, signal, kind, state)
    rig.check_invariants(signal not in ("supply", "valve", "driver"))
    sup = rig.h.ctrl.supervisor
    first = next((t.t_s for t in sup.history if t.new.name == "FAULT"), None)
    assert first is None or first >= at_s - 1e-6, (first, sup.fault_reason)  # none before


def test_a_copy_runs_exactly_as_a_fresh_rig_on_harsh_sensors(safety_rig: RigMaker) -> None:
    """As test_contract.py's equivalence test, on these sensors (sampled, filtered,
    bursty: the sensors' own state and random numbers are copied too)."""
    fresh = safety_rig(80.0, 3.0, [_fault("length", "jump", "running")], sensors="harsh")
    _to_the_fault(fresh, "running")
    fresh.run(AFTER_S)
    copied = _from_a_copy(safety_rig, "length", "jump", "running")
    assert len(copied.ticks) == len(fresh.ticks) > 3000
    assert copied.ticks == fresh.ticks
    assert copied.h.sim.sensor_faults.any
