"""Implausible readings (issue 11): each is a fault naming the sensor, found within
its stated time; the signal is then not trusted (nothing downstream acts on it);
and ordinary runs raise no false alarms."""

from __future__ import annotations

from collections.abc import Callable

import pytest

from pamd.tick import Flag

from .conftest import SafetyRig

# (signal, kind) -> (what the reason says, latest detection after the fault, s); the
# stated times: a jump, an impossible value: the first sample; force zero under
# load: force_zero_s (0.1 s); frozen force/pressure: frozen_s (0.2 s); a stale signal:
# its timeout (0.05 s); a stuck length: once the pressure moved 0.5 bar (here within
# 1.5 s of the 2-5 bar, 0.25 Hz sine); no supply: the tracking band for
# tracking_time_s (1 s) after the command leaves the pressure behind.
DETECTED = {
    ("length", "dead"): ("m1.length reads 0.00 mm", 0.0),
    ("length", "jump"): ("m1.length jumped +", 0.0),
    ("length", "noisy"): ("m1.length jumped", 0.01),
    ("length", "stuck"): ("m1.length frozen at", 1.5),
    ("length", "silent"): ("m1.length from driver 'sim' is stale", 0.051),
    ("force", "dead"): ("m1.force reads 0.0 N for 10", 0.102),
    ("force", "stuck"): ("m1.force frozen at", 0.202),
    ("pressure", "dead"): ("m1.pressure jumped -", 0.0),
    ("pressure", "jump"): ("m1.pressure jumped +", 0.0),
    ("pressure", "noisy"): ("m1.pressure jumped", 0.05),
    ("pressure", "stuck"): ("m1.pressure frozen at", 0.202),
    ("supply", "lost"): ("(m1.pressure) does not follow the command", 1.5),
}


@pytest.mark.parametrize("signal, kind", list(DETECTED), ids=[f"{s}-{k}" for s, k in DETECTED])
def test_each_implausible_reading_is_a_fault_naming_the_sensor_in_its_stated_time(
        safety_rig: Callable[..., SafetyRig], signal: str, kind: str) -> None:
    said, within_s = DETECTED[(signal, kind)]
    rig = safety_rig(80.0, 3.0, [{"at_s": 1.0, "muscle": "m1", "signal": signal,
                                  "kind": kind}])
    rig.run(0.01)
    rig.cmd("profile", kind="sine", min_bar=2.0, max_bar=5.0, freq_hz=0.25)
    rig.run(3.5)
    sup = rig.h.ctrl.supervisor
    assert rig.h.state == "FAULT"
    assert said in sup.fault_reason, sup.fault_reason
    t_fault = next(t.t_s for t in sup.history if t.new.name == "FAULT")
    assert 1.0 <= t_fault <= 1.0 + within_s + 1e-9
    rig.check_invariants()
    # held at the safe pressure
    assert rig.m.valve_cmd_bar == pytest.approx(rig.m.safe_pressure_bar)


def test_an_untrusted_length_moves_no_guard_the_muscle_holds_its_safe_pressure(
        safety_rig: Callable[..., SafetyRig]) -> None:
    # the encoder jumps 9 mm longer: it now reads "stretched 7 %", past the pretension
    # limit. The guard would raise the pressure on that lie; it must not.
    rig = safety_rig(80.0, 3.0, [{"at_s": 1.0, "muscle": "m1", "signal": "length",
                                  "kind": "jump", "size": 9.0}])
    rig.h.keep = True
    rig.run(3.0)
    assert "m1.length jumped +9.00 mm" in rig.h.ctrl.supervisor.fault_reason
    assert rig.m.contraction < -0.06  # what the lying sensor says
    after = [r for r in rig.h.records if r["t_s"] > 1.0]
    assert not any(int(r["m1"]["flags"]) & Flag.PRETENSION_LIMIT for r in after)
    assert rig.m.valve_cmd_bar == pytest.approx(rig.m.safe_pressure_bar)  # open loop, safe pressure
    assert rig.h.ctrl.status()["muscles"]["m1"]["trusted"] == {
        "pressure": True, "force": True, "length": False}
    implausible = [e for e in rig.h.sink.events if e[1] == "implausible"]
    assert implausible[0][2]["trusted"] == ["pressure", "force"]


def test_reset_trusts_the_signal_again_once_it_reads_right(
        safety_rig: Callable[..., SafetyRig]) -> None:
    rig = safety_rig(80.0, 3.0, [{"at_s": 0.5, "muscle": "m1", "signal": "length",
                                  "kind": "dead"}])
    rig.run(1.0)
    assert rig.h.state == "FAULT" and not rig.m.plausibility.length_ok
    rig.h.sim.clear_faults()
    rig.run(0.01)
    rig.cmd("reset")
    rig.run(1.0)
    assert rig.h.state == "IDLE" and rig.m.plausibility.length_ok


@pytest.mark.parametrize("load_kg, low, high", [(0.0, 0.0, 6.0), (30.0, 0.0, 6.0),
                                                (80.0, 1.6, 6.0)])
def test_full_sweeps_raise_no_false_alarm(safety_rig: Callable[..., SafetyRig],
                                          load_kg: float, low: float, high: float) -> None:
    rig = safety_rig(load_kg, low)
    rig.run(0.01)
    rig.cmd("profile", kind="sine", min_bar=low, max_bar=high, freq_hz=0.25, cycles=1)
    rig.run(6.0)
    assert rig.h.ctrl.supervisor.faults == []
    assert not [e for e in rig.h.sink.events if e[1] == "implausible"]


def test_an_isometric_clamp_is_not_a_frozen_length_nor_a_lost_load(
        safety_rig: Callable[..., SafetyRig]) -> None:
    # equal hard stops hold the muscle at 5 % contraction: the length does not move
    # while pressure and force do, and the load cell may read nothing at 0 bar
    rig = safety_rig(30.0, 0.0, drivers=[{"name": "sim", "type": "sim", "options": {
        "seed": 1, "muscles": [{"name": "m1", "load_kg": 30.0, "stop_contraction": 0.05,
                                "stop_stretch_contraction": 0.05}]}}])
    rig.run(0.01)
    rig.cmd("profile", kind="sine", min_bar=0.0, max_bar=6.0, freq_hz=0.25, cycles=1)
    rig.run(5.0)
    assert rig.h.ctrl.supervisor.faults == []


def test_a_reading_found_implausible_while_starting_faults_once_started(
        safety_rig: Callable[..., SafetyRig]) -> None:
    rig = safety_rig(30.0)
    sim = rig.h.sim
    sim.inject_fault("m1", "force", "silent")  # start-up waits for the force ...
    sim.in_stamps_s[1] = -10.0
    sim.inject_fault("m1", "length", "dead")  # ... while the length reads 0 mm
    rig.run(0.02)
    assert rig.h.state == "STARTING" and not rig.m.plausibility.length_ok
    sim.clear_faults()  # the force answers: the rig starts, and faults at once
    rig.run(0.02)
    sup = rig.h.ctrl.supervisor
    assert [t.new.name for t in sup.history] == ["IDLE", "FAULT"]
    assert "m1.length reads 0.00 mm" in sup.fault_reason
    assert "length untrusted" in sup.history[0].reason  # and it ramps to the safe pressure
