"""Faults survive restarts: a latched fault (or emergency stop) and its reason are
saved in the state directory by the main thread; a daemon started again reads its
sensors, holds the measured pressure and latches again, refusing profiles until
`reset`, which removes the file. An unreadable state file latches too."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

import pytest

from pamd.config import LoadedConfig
from pamd.daemon.daemon import Daemon
from pamd.daemon.service.state import state_paths
from pamd.wire.tick import State

from .conftest import wait_until


def run_daemon(cfg: LoadedConfig, **kw: object) -> Daemon:
    d = Daemon(cfg, **kw)  # type: ignore[arg-type]
    d.start()
    return d


def finish(d: Daemon) -> None:
    d.stop("test finished")
    d.wait(timeout_s=30)
    d.close()


def test_a_latched_fault_comes_back_after_a_restart_until_reset(
        sim_config: Callable[..., LoadedConfig]) -> None:
    cfg = sim_config(state_dir="state")
    paths = state_paths(cfg)
    assert paths is not None and paths.fault == str(Path(cfg.path).parent / "state" /
                                                    "fault.json")  # relative to the config
    d1 = run_daemon(cfg)
    try:
        assert d1.wait_for_state((State.IDLE,), 10) == State.IDLE
        assert d1.command("setpoint", {"muscle": "m1", "bar": 2.0})["ok"]
        assert wait_until(lambda: d1.ctrl.muscles[0].pressure_bar > 1.0, 20)
        d1.rig.drivers["sim"].inject_fault("*", "driver", "error")
        assert d1.wait_for_state((State.FAULT,), 10) == State.FAULT
        d1.service()
        saved = json.loads(Path(paths.fault).read_text())
        assert saved["state"] == "FAULT" and "injected driver error" in saved["reason"]
    finally:
        finish(d1)
    assert Path(paths.fault).exists()  # a stop does not clear it

    d2 = run_daemon(cfg)
    try:
        # nothing moves before the sensors are read; then it latches at once
        assert d2.wait_for_state((State.FAULT,), 10) == State.FAULT
        sup = d2.ctrl.supervisor
        assert "injected driver error" in sup.reason and "kept across a restart" in sup.reason
        assert [t.new for t in sup.history] == [State.IDLE, State.FAULT]
        assert sup.history[0].reason.startswith("sensors read; holding measured pressure")
        m = d2.ctrl.muscles[0]
        assert m.started and m.profile is None
        v = d2.command("profile", {"kind": "sine", "min_bar": 0.5, "max_bar": 2.0,
                                   "freq_hz": 0.2})
        assert not v["ok"] and "send reset" in v["error"]  # never resumes by itself
        d2.service()
        assert json.loads(Path(paths.fault).read_text())["reason"] == saved["reason"]
        assert d2.command("reset")["ok"]
        assert wait_until(lambda: (d2.service(), not Path(paths.fault).exists())[1], 10)
    finally:
        finish(d2)

    d3 = run_daemon(cfg)
    try:
        assert d3.wait_for_state((State.IDLE, State.FAULT), 10) == State.IDLE
    finally:
        finish(d3)


def test_an_emergency_stop_comes_back_as_one_and_a_new_latch_keeps_the_old_reason(
        tmp_path: Path, sim_config: Callable[..., LoadedConfig]) -> None:
    """A latched ESTOP comes back after a restart as ESTOP (issue 37 item 5: it came
    back as FAULT), its reason kept; an ESTOP over a restored FAULT keeps the old
    reason as `earlier`."""
    cfg = sim_config()
    state = tmp_path / "state"
    d1 = run_daemon(cfg, state_dir=str(state))
    try:
        assert d1.wait_for_state((State.IDLE,), 10) == State.IDLE
        assert d1.command("estop", {"reason": "hand on the red button"})["ok"]
        d1.service()
    finally:
        finish(d1)
    saved = json.loads((state / "fault.json").read_text())
    assert saved["state"] == "ESTOP" and "hand on the red button" in saved["reason"]

    d2 = run_daemon(cfg, state_dir=str(state))
    try:
        assert d2.wait_for_state((State.ESTOP, State.FAULT), 10) == State.ESTOP
        reason = d2.ctrl.supervisor.reason
        assert "hand on the red button" in reason and "emergency stop latched" in reason
        d2.service()
        kept = json.loads((state / "fault.json").read_text())
        assert kept["state"] == "ESTOP" and kept["reason"] == saved["reason"]  # unchanged
        d2.rig.drivers["sim"].inject_fault("*", "driver", "error")  # ESTOP stays ESTOP
        d2.service()
    finally:
        finish(d2)
    assert json.loads((state / "fault.json").read_text())["reason"] == saved["reason"]

    (state / "fault.json").write_text(json.dumps({**saved, "state": "FAULT"}))
    d3 = run_daemon(cfg, state_dir=str(state))
    try:
        assert d3.wait_for_state((State.FAULT, State.ESTOP), 10) == State.FAULT
        assert d3.command("estop", {"reason": "again"})["ok"]  # ESTOP over the FAULT
        d3.service()
    finally:
        finish(d3)
    again = json.loads((state / "fault.json").read_text())
    assert again["state"] == "ESTOP" and again["reason"] == "emergency stop: again"
    assert again["earlier"] == ["emergency stop: hand on the red button"]


def test_an_unreadable_fault_file_latches(tmp_path: Path,
                                          sim_config: Callable[..., LoadedConfig]) -> None:
    state = tmp_path / "state"
    state.mkdir()
    (state / "fault.json").write_text("{ half a fil")
    d = run_daemon(sim_config(), state_dir=str(state))
    try:
        assert d.wait_for_state((State.FAULT,), 10) == State.FAULT
        assert "unreadable" in d.ctrl.supervisor.reason
        assert d.command("reset")["ok"]
        assert wait_until(lambda: (d.service(), not (state / "fault.json").exists())[1], 10)
    finally:
        finish(d)


def test_a_simulation_keeps_no_state_and_a_real_clock_run_never_beside_the_config(
        sim_config: Callable[..., LoadedConfig], tmp_path: Path,
        monkeypatch: pytest.MonkeyPatch) -> None:
    virtual = sim_config()
    assert state_paths(virtual) is None  # private: no fault latched across runs, no lock
    d = run_daemon(virtual)
    try:
        assert d.wait_for_state((State.IDLE,), 10) == State.IDLE
        assert d.command("estop", {"reason": "in a simulation"})["ok"]
        d.service()
    finally:
        finish(d)
    assert sorted(p.name for p in Path(virtual.path).parent.iterdir()
                  if not p.name.startswith(("locks", "xdg"))) == ["sim.yaml"]
    monkeypatch.setenv("XDG_STATE_HOME", str(tmp_path / "xdg"))
    real = sim_config(loop={"clock": "real"})
    paths = state_paths(real)
    assert paths is not None and paths.directory == str(tmp_path / "xdg" / "pamd" / "sim")
    assert paths.calibration == str(tmp_path / "xdg" / "pamd" / "sim" / "calibration.yaml")


def test_no_state_for_the_builtin_rig_unless_asked(tmp_path: Path) -> None:
    from pamd.config import load_config

    builtin = load_config()
    assert state_paths(builtin) is None  # never write into the installed package
    assert state_paths(builtin, str(tmp_path)).fault == str(tmp_path / "fault.json")
