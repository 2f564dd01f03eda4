"""Commands applied by the loop: references, hold/resume, estop/reset, loads."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from pamd.loop.devices.datum_file import load_calibration
from pamd.wire.tick import State

INCREMENTAL = {"drivers": [{"name": "sim", "type": "sim", "options": {
    "seed": 1, "muscles": [{"name": "m1", "load_kg": 30.0, "length_absolute": False}]}}]}


def test_profile_refused_until_the_length_has_its_datum_then_home_persists(
        harness: Any, tmp_path: Path) -> None:
    h = harness(**INCREMENTAL)  # an incremental encoder: reads 0 mm at power-up
    h.step(0.01)
    assert not h.m1.has_length_datum and h.m1.length_mm == 0.0
    refused = h.cmd("profile", kind="sine", cycles=1)
    assert not refused["ok"] and "send home first" in refused["error"]
    assert h.state == "IDLE" and h.m1.profile is None  # nothing changed
    true_len = h.sim.plant("m1").length_mm
    raw_len = h.m1.length_mm
    ok = h.cmd("home", muscle="m1", length_mm=true_len + 1.0)  # within the tolerance
    assert ok["ok"] and ok["length_offset_mm"] == pytest.approx(1.0 + true_len - raw_len)
    h.step(0.01)
    assert h.m1.length_mm == pytest.approx(true_len + 1.0, abs=0.05)
    assert h.ctrl.calibration_dirty  # saved by the daemon outside the loop's thread
    assert h.cmd("profile", kind="sine", cycles=1)["ok"]


def test_tare_against_the_load_removes_the_drift_and_is_saved_by_the_daemon(
        sim_daemon: Any) -> None:
    # the load cell drifted by +20 N; 30 kg hang on it (issue 11: tare never calls a
    # hanging load zero; it tares against the declared load)
    sig = {k: {"driver": "sim", "channel": f"m1.{k}"} for k in ("pressure", "length")}
    sig["force"] = {"driver": "sim", "channel": "m1.force", "offset": 20.0}
    sig["valve"] = {"driver": "sim", "channel": "m1.valve", "raw_min": 0.0, "raw_max": 6.0}
    d = sim_daemon(muscles=[{"name": "m1", "load_kg": 30.0, "signals": sig}],
                   state_dir="state")  # a simulation keeps its references only if asked
    assert d.wait_for_state((State.IDLE,)) == State.IDLE
    assert d.ctrl.muscles[0].force_n == pytest.approx(30 * 9.80665 + 20.0, abs=5.0)
    refused = d.command("tare", {"muscle": "m1"})
    assert not refused["ok"] and "holds the configured load of 30 kg" in refused["error"]
    assert d.command("tare", {"muscle": "m1", "load_kg": 30.0})["ok"]
    d.service()
    cal = load_calibration(d.cfg.calibration_path)
    assert cal.muscles["m1"].force_offset_n == pytest.approx(20.0, abs=5.0)
    assert cal.muscles["m1"].tared_at
    d.wait_for_state((State.RUNNING,), timeout_s=0.1)  # let a few ticks pass
    assert d.ctrl.muscles[0].force_n == pytest.approx(30 * 9.80665, abs=5.0)


def test_a_simulations_references_hold_for_its_run_only_and_it_says_so(
        sim_daemon: Any, caplog: pytest.LogCaptureFixture, tmp_path: Path) -> None:
    sig = {k: {"driver": "sim", "channel": f"m1.{k}"} for k in ("pressure", "length")}
    sig["force"] = {"driver": "sim", "channel": "m1.force", "offset": 20.0}
    sig["valve"] = {"driver": "sim", "channel": "m1.valve", "raw_min": 0.0, "raw_max": 6.0}
    d = sim_daemon(muscles=[{"name": "m1", "load_kg": 30.0, "signals": sig}])
    assert d.calibration_path is None and d.state is None  # virtual clock: no state
    assert d.wait_for_state((State.IDLE,)) == State.IDLE
    for _ in range(2):
        assert d.command("tare", {"muscle": "m1", "load_kg": 30.0})["ok"]
        d.service()
    said = [r.getMessage() for r in caplog.records if "for this run only" in r.getMessage()]
    assert len(said) == 1 and "--state-dir" in said[0]  # once, with what keeps them
    assert sorted(p.name for p in tmp_path.iterdir()) == ["sim.yaml"]  # no file, no lock


def test_hold_freezes_and_resume_continues_the_profile(harness: Any) -> None:
    h = harness()
    h.step(0.01)
    h.cmd("profile", kind="triangle", min_bar=1.0, max_bar=3.0, freq_hz=0.25, cycles=1)
    h.step(1.5)
    assert h.cmd("hold")["ok"] and h.state == "HOLD"
    frozen = h.m1.setpoint_bar
    h.step(2.0)
    assert h.m1.setpoint_bar == frozen
    assert h.cmd("resume")["ok"] and h.state == "RUNNING"
    h.step(0.01)
    assert h.m1.setpoint_bar == pytest.approx(frozen, abs=0.05)  # continues where it was
    h.step(6.0)
    assert h.state == "IDLE"  # finished its one cycle


def test_a_profile_parameter_its_shape_ignores_is_refused_and_nothing_moves(
        harness: Any) -> None:
    """A constant with cycles would hold forever where the operator asked for one cycle;
    a sine with to_bar never goes there. Each is answered with the reason and never
    starts; the same profile without the parameter runs."""
    h = harness()
    h.step(0.01)
    before = h.m1.setpoint_bar
    for args in ({"kind": "constant", "to_bar": 2.0, "cycles": 1},
                 {"kind": "sine", "min_bar": 1.0, "max_bar": 3.0, "to_bar": 2.0},
                 {"kind": "ramp", "to_bar": 2.0, "duration_s": 3.0}):
        v = h.cmd("profile", **args)
        assert not v["ok"] and f"a {args['kind']} profile does not read" in v["error"], v
        h.step(0.5)
        assert h.state == "IDLE" and h.m1.setpoint_bar == before
    assert h.cmd("profile", kind="constant", to_bar=2.0, duration_s=1.0)["ok"]
    h.step(0.5)
    assert h.state == "RUNNING"


def test_estop_latches_and_reset_needs_the_cause_gone(harness: Any) -> None:
    h = harness(safety={"estop_action": "vent"})
    h.step(0.01)
    h.cmd("setpoint", muscle="m1", bar=3.0)
    h.step(1.5)
    assert h.cmd("estop", reason="operator pressed the button")["ok"]
    h.step(0.002)
    assert h.state == "ESTOP" and h.m1.setpoint_bar == 0.0 and h.m1.exhaust_open  # 30 kg: may vent
    refused = h.cmd("setpoint", muscle="m1", bar=2.0)
    assert not refused["ok"] and "ESTOP" in refused["error"]
    assert h.cmd("reset")["ok"] and h.state == "IDLE"
    assert h.cmd("setpoint", muscle="m1", bar=1.0)["ok"]


def test_estop_vent_is_not_honoured_when_the_load_needs_pressure(harness: Any) -> None:
    h = harness(load_kg=80.0, safety={"estop_action": "vent"}, drivers=[{
        "name": "sim", "type": "sim", "options": {"muscles": [
            {"name": "m1", "load_kg": 80.0, "initial_pressure_bar": 3.0}]}}])
    h.step(0.01)
    h.cmd("estop")
    h.step(2.0)
    safe = h.m1.safe_pressure_bar
    assert h.m1.setpoint_bar == pytest.approx(safe) and safe > 1.0
    assert not h.m1.exhaust_open


def test_load_change_moves_the_safe_pressure_and_is_refused_above_rating(harness: Any) -> None:
    h = harness()
    h.step(0.01)
    assert h.m1.safe_pressure_bar == 0.0
    ok = h.cmd("load", muscle="m1", load_kg=80.0)
    assert ok["ok"] and ok["safe_pressure_bar"] > 1.0
    bad = h.cmd("load", muscle="m1", load_kg=120.0)
    assert not bad["ok"] and "rating" in bad["error"]
    assert h.m1.load_kg == 80.0


def test_500_hz_fallback_and_two_muscles(harness: Any) -> None:
    sig = {"driver": "sim"}
    muscles = []
    for name, load_kg in (("m1", 30.0), ("m2", 50.0)):  # declared as they hang
        s = {k: {**sig, "channel": f"{name}.{k}"} for k in ("pressure", "force", "length")}
        s["valve"] = {**sig, "channel": f"{name}.valve", "raw_max": 6.0}
        muscles.append({"name": name, "load_kg": load_kg, "signals": s})
    h = harness(loop={"rate_hz": 500.0}, muscles=muscles, drivers=[{
        "name": "sim", "type": "sim",
        "options": {"muscles": [{"name": "m1"}, {"name": "m2", "load_kg": 50.0}]}}])
    assert h.period_s == 0.002
    h.step(0.01)
    assert h.cmd("setpoint", muscle="m2", bar=3.0)["ok"]
    h.step(3.0)
    m1, m2 = h.ctrl.muscles
    assert m2.pressure_bar == pytest.approx(3.0, abs=0.03)
    assert m1.pressure_bar == pytest.approx(0.0, abs=0.03)
    assert h.sim.plant("m2").contraction == pytest.approx(0.045, abs=0.01)  # 50 kg, 3 bar


def test_home_uses_the_devices_preset_when_it_has_one(harness: Any) -> None:
    """A device that takes a preset (a CANopen encoder's 0x6003) gets the reference;
    the software offset bridges the time until it confirms, then goes back to 0."""
    h = harness(**INCREMENTAL)
    h.step(0.01)
    sim = h.sim
    idx = h.m1.signals.length.index
    asked: list[tuple[int, float]] = []

    def preset_input(index: int, raw: float) -> bool:
        asked.append((index, raw))
        return True

    sim.preset_input = preset_input
    true_len = h.sim.plant("m1").length_mm
    raw_len = h.m1.length_mm  # 0: the encoder's power-up position
    assert h.cmd("home", muscle="m1", length_mm=true_len + 2.0)["ok"]
    assert asked == [(idx, pytest.approx(true_len + 2.0))]
    h.step(0.01)
    assert h.m1.length_mm == pytest.approx(true_len + 2.0, abs=0.05)  # software offset
    assert h.m1.datums.length_offset_mm == pytest.approx(true_len + 2.0 - raw_len, abs=0.05)
    sim.preset_counts[idx] += 1  # the device confirms: it now reads the reference
    h.step(0.001)
    assert h.m1.datums.length_offset_mm == 0.0 and h.m1.take_calibration_dirty()
