"""The hardware safety chain as signals of the rig (issue 27 item 2), on the simulated
rig stepped tick by tick: the chain opening at 80 kg is an ESTOP that holds the load
(the chain cuts the supply: the valves close and hold, never vent), nothing moves
after it closes until a reset, the heartbeat stops within one tick of a FAULT or a
stall, and a lost supply holds the integrators and is named."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from pamd.wire.tick import Flag, State
from tests.safety.conftest import SafetyRig

CHAIN = {"estop": {"driver": "sim", "channel": "safety_chain"},
         "supply": {"driver": "sim", "channel": "supply"},
         "heartbeat": {"driver": "sim", "channel": "heartbeat"},
         "reset": {"driver": "sim", "channel": "reset"}}
OPEN_AT_S = 0.3
EXHAUST = int(Flag.EXHAUST_OPEN)


def events(rig: SafetyRig, kind: str) -> list[dict[str, Any]]:
    return [d for _, k, d in rig.h.sink.events if k == kind]


def opened_at_80kg(safety_rig: Callable[..., SafetyRig], actuation: str = "proportional",
                   **chain: Any) -> SafetyRig:
    """80 kg held at 5 bar, at rest; the chain opens (an e-stop pressed: the sim's
    schedule) at 0.3 s and stays open for 0.7 s."""
    rig = safety_rig(80.0, 5.0, [{"at_s": OPEN_AT_S, "signal": "safety_chain",
                                  "kind": "open"}], actuation,
                     safety_chain={**CHAIN, **chain})
    rig.h.keep = True
    rig.run(1.0)
    return rig


def test_the_chain_opening_at_80kg_is_an_estop_that_holds_the_load(
        safety_rig: Callable[..., SafetyRig]) -> None:
    rig = opened_at_80kg(safety_rig)
    h, m = rig.h, rig.m
    assert h.state == "ESTOP"
    assert h.ctrl.supervisor.reason.startswith("safety chain open (safety_chain.estop")
    assert events(rig, "safety_chain")[0]["state"] == "open"
    first = next(i for i, k in enumerate(rig.ticks) if k.state == State.ESTOP)
    assert abs(rig.ticks[first].t_s - OPEN_AT_S) < 0.0025  # the tick that read it open
    before, after = rig.ticks[:first], rig.ticks[first:]
    cmd0, p0, x0 = before[-1].cmd, before[-1].pressure_true, before[-1].contraction_true
    # the supply is gone (the chain cut it): the valves close and hold, never vent;
    # the default ESTOP action (`safe_pressure`) would have taken the command down to
    # the safe pressure at 20 bar/s
    assert m.safe_pressure_bar < cmd0 - 2.0
    # the command stands at the pressure the muscle holds (its reading, within the
    # sensor's noise and inside the regulator's hysteresis), not on the way down
    assert min(k.cmd for k in after) >= cmd0 - 0.01
    assert not any(int(r["m1"]["flags"]) & EXHAUST for r in h.records)
    assert min(k.pressure_true for k in after) >= p0 - 0.02
    travel_mm = max(abs(k.contraction_true - x0) for k in after) * 200.0
    assert travel_mm < 0.2
    # the record says why: the chain open, the supply at 0
    last = h.records[-1]
    assert last["safety_chain"] == 0.0 and last["supply_bar"] == 0.0
    assert h.records[round(0.2 / h.period_s)]["safety_chain"] == 1.0
    rig.check_invariants()


def test_onoff_valves_close_and_hold_when_the_chain_opens_at_80kg(
        safety_rig: Callable[..., SafetyRig]) -> None:
    rig = opened_at_80kg(safety_rig, "onoff")
    act = rig.m.actuation
    assert rig.h.state == "ESTOP"
    assert not act.inflate_open and not act.exhaust_open
    after = [k for k in rig.ticks if k.t_s > OPEN_AT_S + 0.05]
    p0 = [k for k in rig.ticks if k.t_s <= OPEN_AT_S - 0.01][-1].pressure_true
    assert min(k.pressure_true for k in after) >= p0 - 0.05
    assert not any(int(r["m1"]["flags"]) & EXHAUST
                   for r in rig.h.records[round(OPEN_AT_S / rig.h.period_s):])


def test_nothing_moves_after_the_chain_closes_until_the_reset(
        safety_rig: Callable[..., SafetyRig]) -> None:
    rig = opened_at_80kg(safety_rig)
    h, m, plant = rig.h, rig.m, rig.plant
    refused = h.cmd("reset")  # the restart interlock: not while the chain is open
    assert not refused["ok"] and "safety chain is still open" in refused["error"]
    h.sim.inject_fault("*", "safety_chain", "closed")  # the e-stop released: air back
    rig.run(0.05)
    cmd0, len0 = m.valve_cmd_bar, plant.length_mm
    rig.run(1.0)
    assert h.state == "ESTOP"
    assert h.records[-1]["safety_chain"] == 1.0 and h.records[-1]["supply_bar"] > 5.0
    assert abs(plant.length_mm - len0) < 0.05
    assert abs(m.valve_cmd_bar - cmd0) < 1e-9
    moved = h.cmd("setpoint", muscle="m1", bar=4.0)
    assert not moved["ok"] and "ESTOP" in moved["error"]
    rig.run(0.3)
    assert abs(plant.length_mm - len0) < 0.05
    assert h.cmd("reset")["ok"]
    assert h.state == "IDLE"
    assert h.cmd("setpoint", muscle="m1", bar=4.0)["ok"]
    rig.run(1.0)
    assert abs(plant.pressure_bar - 4.0) < 0.1
    rig.check_invariants()


def test_the_reset_button_acknowledges_and_reset_by_input_refuses_the_command(
        safety_rig: Callable[..., SafetyRig]) -> None:
    rig = opened_at_80kg(safety_rig, reset_by="input")
    h = rig.h
    h.sim.press_reset()  # pressed while the chain is still open: refused, said
    rig.run(0.01)
    assert h.state == "ESTOP"
    assert events(rig, "reset")[-1]["ok"] is False
    h.sim.press_reset(False)
    h.sim.inject_fault("*", "safety_chain", "closed")
    rig.run(0.1)
    refused = h.cmd("reset")
    assert not refused["ok"] and "reset button at the rig" in refused["error"]
    h.sim.press_reset()
    rig.run(0.01)
    assert h.state == "IDLE"
    assert h.ctrl.supervisor.reason == "reset by operator (reset input)"
    assert events(rig, "reset")[-1]["ok"] is True


def heartbeats(rig: SafetyRig) -> list[float]:
    return [r["heartbeat"] for r in rig.h.records]


def test_the_heartbeat_toggles_every_tick_and_stops_within_one_tick_of_a_lost_device(
        safety_rig: Callable[..., SafetyRig]) -> None:
    rig = safety_rig(30.0, 3.0, [{"at_s": 1.0, "muscle": "m1", "signal": "driver",
                                  "kind": "error"}], safety_chain=CHAIN)
    rig.h.keep = True
    toggles0 = rig.h.sim.heartbeat_toggles
    rig.run(1.5)
    recs = rig.h.records
    beats = heartbeats(rig)
    first = next(i for i, r in enumerate(recs) if r["state"] == int(State.FAULT))
    assert first > 100
    assert all(beats[i] != beats[i - 1] for i in range(1, first))  # every tick
    assert all(b == beats[first - 1] for b in beats[first:])  # stopped at the fault's tick
    # the device saw the same: one toggle per tick up to the fault, none after
    assert rig.h.sim.heartbeat_toggles - toggles0 == first


def test_a_slower_heartbeat_for_a_field_bus_changes_every_heartbeat_toggle_s(
        safety_rig: Callable[..., SafetyRig]) -> None:
    rig = safety_rig(30.0, 3.0, safety_chain={**CHAIN, "heartbeat_toggle_s": 0.005})
    rig.h.keep = True
    rig.run(0.2)
    beats = heartbeats(rig)
    changes = [i for i in range(1, len(beats)) if beats[i] != beats[i - 1]]
    assert len(changes) >= 35
    assert {b - a for a, b in zip(changes, changes[1:], strict=False)} == {5}


def relay_rig(safety_rig: Callable[..., SafetyRig], watchdog_s: float = 0.05,
              faults: list[dict[str, Any]] | None = None) -> SafetyRig:
    """30 kg held at 3 bar, the sim's safety relay watching the heartbeat (as
    config/sim-chain.yaml ships it: 50 ms); the chain latches open when it drops out
    until the safety relay's reset at the rig (the sim's `closed`)."""
    drivers = [{"name": "sim", "type": "sim", "options": {
        "seed": 1, "heartbeat_watchdog_s": watchdog_s, "faults": faults or [],
        "muscles": [{"name": "m1", "load_kg": 30.0, "initial_pressure_bar": 3.0}]}}]
    rig = safety_rig(30.0, drivers=drivers, safety_chain=CHAIN)
    rig.h.keep = True
    return rig


def test_a_stalled_loop_stops_the_heartbeat_and_the_relay_opens_the_chain(
        safety_rig: Callable[..., SafetyRig]) -> None:
    """The sim's safety relay watches the heartbeat (heartbeat_watchdog_s): a loop that
    stalls for 100 ms writes no heartbeat, the relay drops out, cuts the air and opens
    the chain; the first tick after the stall sees it and holds the air. The heartbeat
    beats again from that tick (the loop runs), and once the operator resets the
    safety relay at the rig (the chain closed), `pamd cmd reset` brings the rig back:
    no restart."""
    rig = relay_rig(safety_rig, 0.02)
    h = rig.h
    rig.run(0.5)
    toggles = h.sim.heartbeat_toggles
    assert toggles >= 499 and h.state == "IDLE"
    cmd0 = rig.m.valve_cmd_bar
    h.t += 0.1  # the loop stalls: 100 ms without a tick (nothing writes the heartbeat)
    rig.run(0.001)
    assert h.sim.chain_open and h.sim.chain_opened_by == "heartbeat watchdog"
    assert h.state == "ESTOP" and "safety chain open" in h.ctrl.supervisor.reason
    assert h.sim.heartbeat_toggles <= toggles + 1  # still through the stall (this tick beats)
    rig.run(0.5)
    assert rig.m.valve_cmd_bar >= cmd0 - 0.01  # at the pressure held (within its noise)
    assert h.sim.heartbeat_toggles >= toggles + 499  # beating again, in ESTOP
    assert not h.cmd("reset")["ok"]  # the chain is still open: the interlock
    h.sim.inject_fault("*", "safety_chain", "closed")  # the safety relay reset at the rig
    rig.run(0.1)
    assert h.cmd("reset")["ok"] and h.state == "IDLE"


def test_the_estop_pressed_and_released_under_a_heartbeat_relay_can_be_reset(
        safety_rig: Callable[..., SafetyRig]) -> None:
    """Issue 37 item 4: with the relay of config/sim-chain.yaml (50 ms), press and
    release the e-stop. The heartbeat used to stop at the ESTOP, so the relay opened the
    chain again as soon as the e-stop was released, and every reset was refused
    ("chain still open") until a restart."""
    rig = relay_rig(safety_rig, faults=[
        {"at_s": 0.5, "signal": "safety_chain", "kind": "open"},
        {"at_s": 1.0, "signal": "safety_chain", "kind": "closed"}])
    h = rig.h
    rig.run(1.5)
    assert h.state == "ESTOP"
    assert not h.sim.chain_open, h.sim.chain_opened_by  # the relay held in
    assert h.records[-1]["safety_chain"] == 1.0
    beats = heartbeats(rig)
    assert beats[-1] != beats[-2]  # beating in ESTOP
    assert h.cmd("reset")["ok"] and h.state == "IDLE"


def test_a_fault_keeps_the_heartbeat_and_a_lost_valve_device_stops_it(
        safety_rig: Callable[..., SafetyRig]) -> None:
    """A latched FAULT is pamd's own safe state (its ramp needs the air): the heartbeat
    beats on and the relay keeps the air; a device that carries a valve lost (pamd can
    no longer command the air) stops it until the device answers again."""
    rig = relay_rig(safety_rig, faults=[
        {"at_s": 0.3, "muscle": "m1", "signal": "force", "kind": "silent"}])
    h = rig.h
    rig.run(0.8)
    assert h.state == "FAULT"
    assert not h.sim.chain_open
    beats = heartbeats(rig)
    assert beats[-1] != beats[-2]
    h.sim.inject_fault("*", "driver", "error")
    rig.run(0.1)
    assert h.sim.chain_open and h.sim.chain_opened_by == "heartbeat watchdog"
    toggles = h.sim.heartbeat_toggles
    rig.run(0.1)
    assert h.sim.heartbeat_toggles == toggles


def test_a_lost_supply_holds_the_integrators_and_is_named(
        safety_rig: Callable[..., SafetyRig]) -> None:
    """The air goes at 1 s while the setpoint rises from 3 to 5 bar: the pressure cannot
    follow, and a PID integrating that error would have wound up by the time the air
    returns. With the supply input its integral holds; after supply_lost_s the FAULT
    says "supply lost" (not an anonymous tracking fault a second later)."""
    chain = {"supply": CHAIN["supply"], "supply_lost_s": 0.5}
    faults = [{"at_s": 1.0, "muscle": "*", "signal": "supply", "kind": "lost"}]

    def run(**changes: Any) -> SafetyRig:
        rig = safety_rig(30.0, 3.0, faults, **changes)
        rig.h.keep = True
        rig.run(0.9)
        assert rig.h.cmd("setpoint", muscle="m1", bar=5.0, ramp_s=0.5)["ok"]
        rig.run(0.6)  # 1.5 s: the air out for 0.5 s
        return rig

    held = run(safety_chain=chain)
    recs = held.h.records
    at = round(1.0 / held.h.period_s)
    i_out = [r["m1"]["pid_i_bar"] for r in recs[at + 1:at + 480]]
    assert max(i_out) - min(i_out) < 1e-12  # held
    out = [e for e in events(held, "supply") if e["state"] == "out"]
    assert out and out[0]["supply_bar"] == 0.0
    held.run(0.1)
    assert held.h.state == "FAULT"
    assert held.h.ctrl.supervisor.fault_reason.startswith("supply lost: 0.00 bar below 4 bar")
    refused = held.h.cmd("reset")
    assert not refused["ok"] and "supply is still out" in refused["error"]
    held.h.sim.clear_faults()
    held.run(0.05)
    assert held.h.cmd("reset")["ok"]
    # without the supply input: the integral winds up while the air is out
    free = run()
    wound = [r["m1"]["pid_i_bar"] for r in free.h.records[at + 1:at + 480]]
    assert wound[-1] - wound[0] > 0.3


def test_the_shipped_chain_rig_runs_to_an_estop_holding_its_air_from_the_cli(
        pamd_here: Callable[..., Any], tmp_path: Path) -> None:
    """config/sim-chain.yaml end to end (config, CLI, sim): the e-stop pressed at 2 s is
    an ESTOP naming the chain; the run ends once its muscle holds its air (a hold is
    the safe state there: it never ramps down to the safe pressure, so a run waiting
    for that would go on to its duration and the 30 s ramp deadline after it)."""
    cfg = Path(__file__).resolve().parents[2] / "config" / "sim-chain.yaml"
    r = pamd_here("run", "--config", cfg, "--clock", "virtual", "--duration", "60",
                  "--state-dir", tmp_path, "--no-record", "--json")
    s = json.loads(r.stdout)
    assert r.returncode == 1 and s["final_state"] == "ESTOP"
    assert s["faults"][0].startswith("safety chain open (safety_chain.estop")
    assert s["duration_s"] < 10.0  # ended once its air was held, not by the duration
    # held at the 5 bar it had (within the pressure sensor's 3 mbar noise), never vented
    assert s["outputs"]["m1"]["valve_cmd_bar"] == pytest.approx(5.0, abs=0.01)
    assert "IDLE -> ESTOP: safety chain open" in r.stderr


def test_a_stalled_loop_excuses_the_chain_inputs_age_as_the_muscles(
        safety_rig: Callable[..., SafetyRig]) -> None:
    """A reading that aged while the loop stalled is not an open chain (issue 37 item 5):
    the chain's inputs take the stall's excuse the muscles' inputs take, and the excuse
    lasts the chain's timeouts too. Without it, the e-stop input is open by its age."""
    rig = safety_rig(30.0, 3.0, safety_chain=CHAIN)
    rig.run(0.1)
    ctrl = rig.h.ctrl
    chain = ctrl.chain
    b = chain.estop
    assert b is not None
    late = b.driver.in_stamps_s[b.index] + b.timeout_s + 0.03  # 30 ms too old
    chain.read(late)
    assert chain.open_reason is not None and "no reading within" in chain.open_reason
    chain.open_reason = None
    assert ctrl.excuse_stall(0.04) >= b.timeout_s
    assert chain.stall_excuse_s == 0.04
    chain.read(late)
    assert chain.open_reason is None
    ctrl.excuse_stall(0.0)
