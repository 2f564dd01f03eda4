"""Config reload in the running daemon (what SIGHUP triggers): gains and timeouts
apply at once through the loop's mailbox; limits and loads only while IDLE
(deferred until then); drivers and wiring are refused (restart); a broken file is
refused; a held pressure above a new limit refuses the reload as a whole."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import yaml

from pamd.config import load_config
from pamd.daemon.daemon import Daemon
from pamd.daemon.service.reload import changed_paths, classify
from pamd.wire.tick import State

from .conftest import merge, wait_until

SIM_YAML = Path(__file__).resolve().parents[2] / "config" / "sim.yaml"


def virtual_dict(**changes: Any) -> dict[str, Any]:
    base = yaml.safe_load(SIM_YAML.read_text())
    base["loop"]["clock"] = "virtual"
    base["loop"]["realtime"] = {"enabled": False}
    return merge(base, changes)


def reload_and_wait(d: Daemon) -> None:
    d.request_reload()
    d.service()
    assert wait_until(lambda: (d.service(), d.keeper.pending is None)[1], 20)


def test_classes_of_change() -> None:
    assert classify("control.pid.kp") == "now"
    assert classify("control.rate_feedforward_s") == "now"
    assert classify("safety.signal_timeout_s") == "now"
    assert classify("muscles[1].signals.force.timeout_s") == "now"
    assert classify("loop.stall_timeout_s") == "now"
    assert classify("control.slew_limit_bar_per_s") == "idle"
    assert classify("safety.pressure_margin_bar") == "idle"
    assert classify("muscles[0].limits.max_pressure_bar") == "idle"
    assert classify("muscles[0].load_kg") == "idle"
    for path in ("drivers[0].options.seed", "drivers[]", "muscles[]", "muscles[0].name",
                 "muscles[0].signals.valve.raw_max", "loop.rate_hz", "loop.clock",
                 "recording.dir", "rig_id", "state_dir", "calibration_file",
                 "muscles[0].force_model", "control.some_new_section.gain"):
        assert classify(path) == "restart", path


def test_changed_paths_name_each_key(tmp_path: Path) -> None:
    a = tmp_path / "a.yaml"
    b = tmp_path / "b.yaml"
    a.write_text(yaml.safe_dump(virtual_dict()))
    b.write_text(yaml.safe_dump(virtual_dict(control={"pid": {"kp": 0.5}},
                                             safety={"tracking_time_s": 2.0})))
    assert changed_paths(load_config(str(a)), load_config(str(b))) == [
        "control.pid.kp", "safety.tracking_time_s"]


def test_gains_at_once_limits_deferred_until_idle(tmp_path: Path) -> None:
    path = tmp_path / "rig.yaml"
    path.write_text(yaml.safe_dump(virtual_dict()))
    d = Daemon(load_config(str(path)))
    d.start()
    try:
        assert d.wait_for_state((State.IDLE,), 10) == State.IDLE
        v = d.command("profile", {"kind": "sine", "min_bar": 0.5, "max_bar": 2.0,
                                  "freq_hz": 0.2})
        assert v["ok"], v
        m = d.ctrl.muscles[0]
        safe_before = m.safe_pressure_bar
        path.write_text(yaml.safe_dump(virtual_dict(
            control={"pid": {"kp": 0.5, "ki_per_s": 10.0}},
            safety={"signal_timeout_s": 0.08},
            muscles=[dict(virtual_dict()["muscles"][0], load_kg=60.0,
                          limits={"max_pressure_bar": 5.0})])))
        reload_and_wait(d)
        assert d.ctrl.supervisor.state == State.RUNNING
        pid = m.pressure_loop.pid
        assert (pid.kp, pid.ki, m.inputs.timeouts_s[0]) == (0.5, 10.0, 0.08)  # at once
        assert m.signals.pressure.timeout_s == 0.08
        assert (m.envelope.max_pressure_bar, m.load_kg, m.safe_pressure_bar) == (
            6.0, 30.0, safe_before)  # not yet
        assert d.keeper.deferred is not None
        assert "waiting for the rig to rest" in d.keeper.status_text()
        assert d.command("stop")["ok"]
        assert wait_until(lambda: (d.service(), d.keeper.deferred is None
                                   and d.keeper.pending is None)[1], 20)
        assert (m.envelope.max_pressure_bar, m.load_kg) == (5.0, 60.0)
        assert m.envelope.hard_max_pressure_bar == 5.0 + 0.3
        assert m.safe_pressure_bar > safe_before  # 60 kg needs pressure
        assert d.cfg.rig.muscles[0].load_kg == 60.0  # all of it in force now
    finally:
        d.stop("test finished")
        d.wait(timeout_s=30)
        d.close()


def test_refused_reloads_change_nothing(tmp_path: Path,
                                        sim_daemon: Callable[..., Daemon]) -> None:
    d = sim_daemon()
    assert d.wait_for_state((State.IDLE,), 10) == State.IDLE
    path = Path(d.cfg.path)
    original = yaml.safe_load(path.read_text())
    m = d.ctrl.muscles[0]
    kp = m.pressure_loop.pid.kp
    # a broken file
    path.write_text(yaml.safe_dump(merge(original, {"control": {"pid": {"kp": -1}}})))
    reload_and_wait(d)
    assert m.pressure_loop.pid.kp == kp
    note = d.ctrl.status()["reload"]  # status says why (it showed nothing of a broken file)
    assert note["outcome"] == "refused" and "control.pid.kp" in note["reason"], note
    path.write_text("muscles: [unclosed\n")  # not even YAML
    reload_and_wait(d)
    note = d.ctrl.status()["reload"]
    assert note["outcome"] == "refused" and f"{path}:" in note["reason"], note
    # a new driver option with a new gain: needs a restart, so nothing applies
    drv = original["drivers"][0]
    changed = merge(original, {"control": {"pid": {"kp": 0.9}}})
    changed["drivers"] = [dict(drv, options=dict(drv["options"], seed=7))]
    path.write_text(yaml.safe_dump(changed))
    reload_and_wait(d)
    assert m.pressure_loop.pid.kp == kp
    note = d.ctrl.reload_note
    assert note is not None and note["outcome"] == "refused", note
    assert "drivers[0].options.seed" in note["reason"] and "restart" in note["reason"], note
    # a pressure limit below the pressure the muscle holds
    v = d.command("profile", {"kind": "constant", "to_bar": 3.0, "duration_s": 0.2})
    assert v["ok"], v  # ends IDLE, holding 3 bar
    assert wait_until(lambda: abs(m.setpoint_bar - 3.0) < 1e-6 and d.ctrl.supervisor.state
                      == State.IDLE, 20)
    low = merge(original, {"control": {"pid": {"kp": 0.9}}})
    low["muscles"][0]["limits"] = {"max_pressure_bar": 2.0}
    path.write_text(yaml.safe_dump(low))
    d.request_reload()
    d.service()
    plan, pending = d.keeper.pending
    verdict = pending.result(10)
    assert not verdict["ok"] and "holds 3.00 bar" in verdict["error"]
    assert (m.pressure_loop.pid.kp, m.envelope.max_pressure_bar) == (kp, 6.0)


CUSTOM_YAML = SIM_YAML.parent / "sim-custom.yaml"


def _custom_rig(tmp_path: Path) -> Path:
    """config/sim-custom.yaml on the virtual clock, its map copied beside it."""
    (tmp_path / "maps").mkdir()
    table = CUSTOM_YAML.parent / "maps" / "specimen-20.csv"
    (tmp_path / "maps" / "specimen-20.csv").write_text(table.read_text())
    data = yaml.safe_load(CUSTOM_YAML.read_text())
    data["loop"].update(clock="virtual", realtime={"enabled": False})
    path = tmp_path / "rig.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def _edit_map(path: Path, scale: float) -> None:
    """The map's forces scaled by `scale` (1.0: rewritten, reformatted, the same rows)."""
    lines = path.read_text().splitlines()
    out = []
    for ln in lines:
        cells = ln.split(",")
        if len(cells) == 3 and cells[2].strip().replace(".", "", 1).isdigit():
            ln = f"{cells[0]}, {cells[1]}, {float(cells[2]) * scale!r}"
        out.append(ln)
    path.write_text("# rewritten\n" + "\n".join(out) + "\n")


def test_a_custom_map_edited_on_disk_is_a_change_as_a_changed_type_is(tmp_path: Path) -> None:
    """Issue 44's custom.map_file: the config's text unchanged, its map edited on disk.
    A reload compares what the config resolves to (the map's rows, by their digest), so
    the edit is a change that needs a restart (as a changed `type`), said with the file;
    a map rewritten with the same rows is none."""
    from pamd.daemon.service.reload import describe, plan_reload

    path = _custom_rig(tmp_path)
    table = tmp_path / "maps" / "specimen-20.csv"
    old = load_config(str(path))
    _edit_map(table, 1.0)
    same = load_config(str(path))
    assert same.text == old.text and changed_paths(old, same) == []
    _edit_map(table, 1.05)
    new = load_config(str(path))
    assert new.text == old.text
    assert changed_paths(old, new) == ["muscles[0].custom.map_sha256"]
    assert classify("muscles[0].custom.map_sha256") == classify("muscles[0].type") == "restart"
    plan = plan_reload(old, old, old, new)
    assert plan.restart == ["muscles[0].custom.map_sha256"] and not plan.now + plan.idle
    said = describe(plan.restart, old, new)
    digest = old.muscle_type("m1").map_sha256
    assert digest is not None and said.startswith(f"muscles[0].custom.map_sha256 {digest[:12]}")
    assert said.count(str(table)) == 2, said


def test_a_reload_notices_a_custom_map_edited_on_disk(tmp_path: Path) -> None:
    """The running daemon (virtual clock: it cannot restart in place) refuses the reload
    of an edited map as it refuses any change that reopens the devices, and its status
    says so; the map in force stays the one it started with."""
    path = _custom_rig(tmp_path)
    d = Daemon(load_config(str(path)))
    d.start()
    try:
        assert d.wait_for_state((State.IDLE,), 10) == State.IDLE
        safe = d.ctrl.muscles[0].safe_pressure_bar
        _edit_map(tmp_path / "maps" / "specimen-20.csv", 0.9)
        reload_and_wait(d)
        note = d.ctrl.status()["reload"]
        assert note["outcome"] == "refused", note
        assert "muscles[0].custom.map_sha256" in note["reason"], note
        assert "needs a restart" in note["reason"], note
        assert d.ctrl.muscles[0].safe_pressure_bar == safe
    finally:
        d.stop("test finished")
        d.wait(timeout_s=30)
        d.close()
