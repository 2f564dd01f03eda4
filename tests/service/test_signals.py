"""Signals as systemd sends them to `pamd run`: SIGTERM mid-profile reaches the safe
state, finalises the recording and exits 0; SIGHUP reloads the config (a broken
one is refused and the daemon keeps running; a changed gain applies at once; a
changed driver restarts in place, test_restart.py); SIGINT stops like SIGTERM."""

from __future__ import annotations

import json
import signal
from pathlib import Path

from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory

from .conftest import NotifySocket, sim_dict, write_yaml


def read_recording(path: Path) -> tuple[object, dict[str, dict[str, str]], list[object]]:
    """(summary, metadata by name, state messages of m1) of a finalised MCAP file."""
    with open(path, "rb") as fh:
        reader = make_reader(fh, decoder_factories=[DecoderFactory()])
        summary = reader.get_summary()
        meta = {m.name: dict(m.metadata) for m in reader.iter_metadata()}
        states = [msg for _s, _c, _m, msg in reader.iter_decoded_messages(
            topics=["/pamd/sim/state/m1"])]
    return summary, meta, states


def test_sigterm_mid_profile_safe_state_recording_finalised_exit_0(
        tmp_path: Path, notify: NotifySocket, pamd_run) -> None:
    cfg = write_yaml(tmp_path / "rig.yaml", sim_dict())
    rec = tmp_path / "rec"
    p = pamd_run("--config", cfg, "--state-dir", tmp_path / "state", "--profile", "sine",
                 "--record", rec, "--json", env=notify.env(400_000))
    assert p.wait_log("sine profile started", 60), p.log()
    assert p.until(lambda: any(s.startswith("RUNNING") for s in notify.statuses()), 30)
    n = notify.count("WATCHDOG=1")  # pings every 0.1 s: ~1 s into the lead-in
    assert p.until(lambda: notify.count("WATCHDOG=1") >= n + 10, 30)
    p.send(signal.SIGTERM)
    assert p.proc.wait(90) == 0, p.log()  # one signal, as systemd sends it
    out = json.loads(p.stdout())
    assert out["stop_reason"] == "SIGTERM received"
    assert out["final_state"] == "IDLE" and out["faults"] == []
    assert notify.index("STOPPING=1") > notify.index("WATCHDOG=1")
    files = sorted(rec.glob("*.mcap"))
    assert len(files) == 1 and [str(f) for f in files] == out["recording"]["files"]
    summary, meta, states = read_recording(files[0])
    assert summary is not None  # the summary section and footer: the file was finalised
    assert meta["pamd.summary"]["stop_reason"] == "SIGTERM received"
    assert meta["pamd.summary"]["final_state"] == "IDLE"
    sps = [m.setpoint_bar for m in states]
    assert max(sps) > 0.5  # it was mid-profile, the pressure up
    last = states[-1]  # and the last tick recorded is at the safe state
    assert abs(last.setpoint_bar - last.safe_pressure_bar) < 1e-9
    assert len(states) == out["ticks"]


def test_sighup_reload_refuses_a_broken_config_and_applies_a_new_gain(
        tmp_path: Path, notify: NotifySocket, pamd_run) -> None:
    good = sim_dict()
    cfg = write_yaml(tmp_path / "rig.yaml", good)
    p = pamd_run("--config", cfg, "--state-dir", tmp_path / "state", "--json",
                 env=notify.env(400_000))
    assert p.wait_log("sensors read", 60), p.log()
    assert p.until(lambda: notify.index("READY=1") >= 0, 30)

    broken = sim_dict(safety={"tracking_band_bar": -1})
    write_yaml(cfg, broken)
    p.send(signal.SIGHUP)
    assert p.wait_log("reload refused", 30), p.log()
    assert "safety.tracking_band_bar" in p.log() and f"{cfg}:" in p.log()
    assert p.proc.poll() is None  # still running, on the old config
    assert p.until(lambda: notify.count("READY=1") >= 2, 30)  # reload answered
    assert notify.index("RELOADING=1") > notify.index("WATCHDOG=1")
    n = notify.count("WATCHDOG=1")
    assert p.until(lambda: notify.count("WATCHDOG=1") >= n + 3, 30)  # and ticking

    shipped_kp = sim_dict()["control"]["pid"]["kp"]  # the gain config/sim.yaml ships
    write_yaml(cfg, sim_dict(control={"pid": {"kp": 0.45}}))
    p.send(signal.SIGHUP)
    assert p.wait_log(f"reload: applied at once: control.pid.kp {shipped_kp:g} -> 0.45", 30), \
        p.log()

    p.send(signal.SIGINT)  # like SIGTERM: safe state, exit 0
    assert p.proc.wait(90) == 0, p.log()  # one signal, as systemd sends it
    out = json.loads(p.stdout())
    assert out["stop_reason"] == "SIGINT received" and out["final_state"] == "IDLE"
    assert out["faults"] == []
