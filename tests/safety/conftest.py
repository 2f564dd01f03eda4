"""The safety suite's rig: the simulated DMSP-20 with a load and a scripted fault
schedule (the sim driver's `faults` option), stepped tick by tick on the virtual
clock through `pamd.loop.harness.Harness`, with what each tick did kept for the
invariant checks."""

from __future__ import annotations

import copy
import functools
import math
import pickle
from collections.abc import Callable, Hashable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, NamedTuple

import pytest
import yaml

from pamd.config import LoadedConfig
from pamd.loop.harness import Harness
from pamd.sim.faults import SimFault
from pamd.wire.tick import State

from ..conftest import sim_dict

SAFE_STATES = (State.FAULT, State.ESTOP)


class Tick(NamedTuple):
    """What one tick did, as the invariants need it (a tuple: thousands a run)."""

    t_s: float
    state: State  # the state the muscle's tick ran in
    safe: bool  # FAULT, ESTOP or a safe ramp
    sp: float
    cmd: float
    safe_bar: float
    pressure_true: float
    contraction_true: float


@dataclass
class SafetyRig:
    h: Harness
    ticks: list[Tick] = field(default_factory=list)

    @property
    def m(self) -> Any:
        return self.h.m1

    @property
    def plant(self) -> Any:
        return self.h.sim.plant("m1")

    def run(self, seconds: float) -> None:
        """Step tick by tick, keeping what each tick did."""
        h, m, plant = self.h, self.h.m1, self.h.sim.plant("m1")
        supervisor, step, period_s, keep = h.ctrl.supervisor, h.step, h.period_s, self.ticks.append
        starting = State.STARTING
        for _ in range(round(seconds / period_s)):
            before = supervisor.state
            step(period_s)
            after = supervisor.state
            # the chain's ESTOP and the estop command latch before the muscles tick
            ran_in = after if before == starting or after == State.ESTOP else before
            if not m.started:
                continue
            # the tick that found a fault (latched at its end) is the safe state's entry:
            # it is held to the safe state's invariants too (issue 23)
            entry = after in SAFE_STATES and before not in SAFE_STATES
            keep(Tick(h.t, ran_in, entry or ran_in in SAFE_STATES or m.in_safe_ramp,
                      m.setpoint_bar, m.valve_cmd_bar, m.safe_pressure_bar,
                      plant.pressure_bar, plant.contraction))

    def run_until(self, t_s: float) -> None:
        """Step up to the tick that starts at `t_s` (not yet run): the one a fault
        scheduled at `t_s` strikes in. By the clock, not a tick count, as a command given
        while the rig starts waits for its sensors (more ticks)."""
        h = self.h
        if h.t > t_s + 0.5 * h.period_s:
            raise AssertionError(f"the rig is past {t_s} s already (at {h.t:.3f} s)")
        self.run(max(t_s - h.t, 0.0))

    def cmd(self, verb: str, **payload: Any) -> dict[str, Any]:
        v = self.h.cmd(verb, **payload)
        assert v["ok"], v
        return v

    def check_invariants(self, actuator_works: bool = True) -> None:
        """The safety contract over the whole run (issue 11):

        * the command is never above the pressure limit nor below 0;
        * in a safe state (FAULT, ESTOP, a safe ramp) it moves at most at the slew limit,
          never falls below the safe pressure, and while below it never falls at all;
        * in a safe state the setpoint only ever moves towards the safe pressure (no
          guard writes it);
        * the muscle stays inside its hard contraction limits, where the physics allows
          it (the valve, the supply and the driver still work).
        """
        m = self.m
        eps = 1e-9
        step = m.envelope.safe_slew_bar_per_s * self.h.period_s
        estop_step = m.envelope.estop_slew_bar_per_s * self.h.period_s
        prev: Tick | None = None
        for k in self.ticks:
            where = f"t={k.t_s:.3f} s {k.state.name}{' (safe)' if k.safe else ''}"
            assert 0.0 <= k.cmd <= m.envelope.max_pressure_bar + eps, (
                f"{where}: command {k.cmd:.3f} bar")
            if prev is not None and k.safe:
                lim = estop_step if k.state == State.ESTOP else step
                assert abs(k.cmd - prev.cmd) <= lim + eps, (
                    f"{where}: command moved {k.cmd - prev.cmd:+.4f} bar in one tick "
                    f"(slew limit {lim:.4f})")
                assert k.cmd >= min(k.safe_bar, prev.cmd) - eps, (
                    f"{where}: command {k.cmd:.3f} bar below the safe pressure "
                    f"{k.safe_bar:.3f} bar (was {prev.cmd:.3f})")
                if prev.safe:
                    assert abs(k.sp - k.safe_bar) <= abs(prev.sp - k.safe_bar) + eps, (
                        f"{where}: setpoint {k.sp:.3f} moved away from the safe pressure")
            if actuator_works:
                env = m.envelope
                assert (-env.hard_max_pretension - 1e-3 <= k.contraction_true
                        <= env.hard_max_contraction + 1e-3), (
                    f"{where}: contraction {100 * k.contraction_true:.2f} % outside the hard "
                    "limits")
            prev = k

    def min_safe_command(self) -> float:
        """The lowest command written in a safe state after it reached the safe
        pressure (the figure the bench reports)."""
        reached = False
        low = math.inf
        for k in self.ticks:
            if not k.safe:
                reached = False
                continue
            if not reached and k.cmd >= k.safe_bar - 1e-9:
                reached = True
            if reached:
                low = min(low, k.cmd)
        return low


HARSH_YAML = Path(__file__).resolve().parents[2] / "config" / "sim-harsh.yaml"
#: the sensor sets the safety and plausibility suites run on: config/sim.yaml's (a 1 kHz
#: DAQ card with noise) and config/sim-harsh.yaml's (quantised, noiseless, filtered, slow,
#: late and bursty: a real rig's worst case)
SENSOR_SETS = ("sim", "harsh")


@functools.cache
def _harsh() -> dict[str, Any]:
    return yaml.safe_load(HARSH_YAML.read_text())


def sensor_options(sensors: str) -> dict[str, Any]:
    """The sim muscle's sensor options of a sensor set (nothing for config/sim.yaml's)."""
    if sensors == "sim":
        return {}
    muscle = dict(_harsh()["drivers"][0]["options"]["muscles"][0])
    for key in ("name", "nominal_length_mm", "load_kg"):
        muscle.pop(key, None)
    return muscle


def sensor_signals(sensors: str) -> dict[str, Any]:
    """The rig's `signals:` of m1 in a sensor set (periods and timeouts that fit them)."""
    base = _harsh() if sensors == "harsh" else yaml.safe_load(
        (HARSH_YAML.parent / "sim.yaml").read_text())
    return copy.deepcopy(base["muscles"][0]["signals"])


def sensor_delay_s(sensors: str, signal: str) -> float:
    """How long after a change its sensor may take to show it: a sample period, the
    latency and a burst's hold (0 for config/sim.yaml's 1 kHz card)."""
    o = sensor_options(sensors)
    return (o.get(f"{signal}_sample_period_s", 0.0) + o.get(f"{signal}_latency_s", 0.0)
            + o.get(f"{signal}_burst_s", 0.0))


def sim_driver(load_kg: float, initial_bar: float,
               faults: list[dict[str, Any]] | None = None,
               actuation: str = "proportional", sensors: str = "sim",
               **muscle_options: Any) -> list[dict[str, Any]]:
    """The `drivers:` of a rig with one muscle carrying `load_kg`, its regulator (or its
    on/off valves) holding `initial_bar` at power-up, its sensors as in the sensor set
    `sensors`, and the fault schedule."""
    muscle = {"name": "m1", "load_kg": load_kg, "initial_pressure_bar": initial_bar,
              "actuation": actuation, **sensor_options(sensors), **muscle_options}
    return [{"name": "sim", "type": "sim", "options": {
        "seed": 1, "faults": faults or [], "muscles": [muscle]}}]


def onoff_muscles(load_kg: float) -> list[dict[str, Any]]:
    """The `muscles:` of config/sim.yaml's m1 on on/off valves (as config/sim-onoff.yaml)."""
    return [{"name": "m1", "type": "dmsp20", "nominal_length_mm": 200, "load_kg": load_kg,
             "actuation": "onoff",
             "signals": {"pressure": {"driver": "sim", "channel": "m1.pressure"},
                         "force": {"driver": "sim", "channel": "m1.force"},
                         "length": {"driver": "sim", "channel": "m1.length"},
                         "inflate": {"driver": "sim", "channel": "m1.inflate"},
                         "exhaust": {"driver": "sim", "channel": "m1.exhaust"}}}]


class RigMaker:
    """Makes safety rigs (`__call__`) and closes each, and each it adopts, at the end
    of the test."""

    def __init__(self, sim_config: Callable[..., LoadedConfig]) -> None:
        self._sim_config = sim_config
        self._made: list[Harness] = []

    def __call__(self, load_kg: float, initial_bar: float = 0.0,
                 faults: list[dict[str, Any]] | None = None,
                 actuation: str = "proportional", sensors: str = "sim",
                 dead_weight: bool = True, **changes: Any) -> SafetyRig:
        """`dead_weight` False: the load does not hang freely (the sim's stops clamp the
        muscle, say), so the start-up's load check does not apply."""
        changes.setdefault("drivers", sim_driver(load_kg, initial_bar, faults, actuation,
                                                 sensors))
        if actuation == "onoff":
            changes.setdefault("muscles", onoff_muscles(load_kg))
        elif sensors != "sim":
            muscle = copy.deepcopy(sim_dict(load_kg)["muscles"][0])
            muscle["signals"] = sensor_signals(sensors)
            changes.setdefault("muscles", [muscle])
        if not dead_weight:
            muscles = copy.deepcopy(changes.get("muscles") or sim_dict(load_kg)["muscles"])
            muscles[0]["dead_weight"] = False
            changes["muscles"] = muscles
        return self.adopt(SafetyRig(Harness(self._sim_config(load_kg, **changes))))

    def adopt(self, rig: SafetyRig) -> SafetyRig:
        """`rig` (e.g. a copy of another) is closed with the ones made here."""
        self._made.append(rig.h)
        return rig

    def close(self) -> None:
        for h in self._made:
            h.rig.close()


#: scenario key -> a rig run fault-free to its fault time, pickled (see `from_a_copy`)
_AT_THE_FAULT: dict[Hashable, bytes] = {}


def from_a_copy(maker: RigMaker, scenario: Hashable, build: Callable[[], SafetyRig],
                to_the_fault: Callable[[SafetyRig], None],
                fault: dict[str, Any]) -> SafetyRig:
    """A rig of `scenario` at its fault time, about to fail as `fault` says: a copy of
    the scenario's rig made by `build` (with no fault scheduled) and run by
    `to_the_fault` up to the tick the fault strikes at. The run up to a fault does not
    depend on which fault is to come, so each worker runs it once per scenario; the copy
    then runs exactly as a rig built with the fault in its schedule would
    (test_contract.py's and test_contract_harsh.py's equivalence tests). The rig is
    kept pickled: a copy unpickled takes a fifth of a deep copy's time."""
    if scenario not in _AT_THE_FAULT:
        first = build()
        to_the_fault(first)
        _AT_THE_FAULT[scenario] = pickle.dumps(first)  # before the fixture closes `first`
    rig = maker.adopt(pickle.loads(_AT_THE_FAULT[scenario]))
    rig.h.sim.schedule_faults([SimFault(**fault)])
    return rig


@pytest.fixture
def safety_rig(sim_config: Callable[..., LoadedConfig]) -> Iterator[RigMaker]:
    maker = RigMaker(sim_config)
    yield maker
    maker.close()


from tests.control.conftest import static_model  # noqa: E402, F401  (the one model fixture)
