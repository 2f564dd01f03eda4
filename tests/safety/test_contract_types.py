"""The safety contract (tests/safety/test_contract.py) on the other muscle types (issue
44): a DMSP-40 rig at 100 kg (config/sim-dmsp40.yaml: the type's ratings and map, the
simulated muscle a DMSP-40) and a custom muscle at 30 kg (config/sim-custom.yaml: the
lab's table converted from kPa and %, the simulated muscle pulling with the same
table). The invariants are the same; the limits, the safe pressure and the plant are
each type's.

Every fault kind x every state on both rigs is `-m slow` (216 runs); the default run
takes a spread of nine: every state and every signal (each sensor two different
ways) at least once over the two rigs."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
import yaml

from .conftest import RigMaker, SafetyRig, from_a_copy, sim_driver
from .test_contract import AFTER_S, FAULTS, STATES, _fault, _initial_bar, _to_the_fault

REPO = Path(__file__).resolve().parents[2]
#: rig -> (its config, the load, the simulated muscle's options beyond the config's)
TYPE_RIGS: dict[str, tuple[str, float]] = {
    "dmsp40-100kg": ("sim-dmsp40.yaml", 100.0),
    "custom-30kg": ("sim-custom.yaml", 30.0),
}
#: the default run's spread: (rig, signal, kind, state)
SPREAD = [("dmsp40-100kg", "length", "dead", "running"),
          ("dmsp40-100kg", "pressure", "jump", "safe_ramp"),
          ("dmsp40-100kg", "supply", "lost", "estop"),
          ("dmsp40-100kg", "valve", "stuck", "startup"),
          ("custom-30kg", "force", "stuck", "hold"),
          ("custom-30kg", "pressure", "silent", "idle"),
          ("custom-30kg", "driver", "error", "running"),
          ("custom-30kg", "length", "jump", "safe_ramp"),
          ("custom-30kg", "force", "noisy", "startup")]


def _changes(rig: str, initial_bar: float, faults: list[dict[str, Any]]) -> dict[str, Any]:
    """The rig config's drivers, muscle and gains (the muscle's map made absolute), the
    power-up pressure and the fault schedule."""
    name, load_kg = TYPE_RIGS[rig]
    raw = yaml.safe_load((REPO / "config" / name).read_text())
    sim = dict(raw["drivers"][0]["options"]["muscles"][0])
    for key in ("name", "load_kg"):
        sim.pop(key)
    muscle = raw["muscles"][0]
    if "custom" in muscle:
        muscle["custom"]["map_file"] = str(REPO / "config" / muscle["custom"]["map_file"])
    return {"drivers": sim_driver(load_kg, initial_bar, faults, **sim), "muscles": [muscle],
            "control": raw["control"]}


def _rig(safety_rig: RigMaker, rig: str, signal: str, kind: str, state: str) -> SafetyRig:
    """As test_contract.py's `_fresh` (start-up) or `_from_a_copy`, on `rig`."""
    _, load_kg = TYPE_RIGS[rig]
    bar = _initial_bar(state, load_kg)
    if state == "startup":
        made = safety_rig(load_kg, bar, **_changes(rig, bar, [_fault(signal, kind, state)]))
        _to_the_fault(made, state, load_kg)
    else:
        made = from_a_copy(
            safety_rig, ("contract-types", rig, state),
            lambda: safety_rig(load_kg, bar, **_changes(rig, bar, [])),
            lambda r: _to_the_fault(r, state, load_kg), _fault(signal, kind, state))
    made.run(AFTER_S)
    return made


def _check(made: SafetyRig, rig: str, signal: str) -> None:
    env = made.m.envelope
    assert env.muscle_type == rig.split("-")[0]  # the type's envelope, not a DMSP-20's
    made.check_invariants(signal not in ("supply", "valve", "driver"))


@pytest.mark.parametrize(("rig", "signal", "kind", "state"), SPREAD,
                         ids=[f"{r}-{s}-{k}-{st}" for r, s, k, st in SPREAD])
def test_the_invariants_hold_on_every_type(safety_rig: RigMaker, rig: str, signal: str,
                                           kind: str, state: str) -> None:
    _check(_rig(safety_rig, rig, signal, kind, state), rig, signal)


@pytest.mark.slow
@pytest.mark.parametrize("state", STATES)
@pytest.mark.parametrize("rig", list(TYPE_RIGS))
@pytest.mark.parametrize(("signal", "kind"), FAULTS, ids=[f"{s}-{k}" for s, k in FAULTS])
def test_the_invariants_hold_on_every_type_whatever_fails(
        safety_rig: RigMaker, rig: str, signal: str, kind: str, state: str) -> None:
    _check(_rig(safety_rig, rig, signal, kind, state), rig, signal)

