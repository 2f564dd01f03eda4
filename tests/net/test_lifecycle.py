"""Start-up and shutdown over the network: a taken endpoint refuses before anything
moves, clients say clearly when no daemon answers, a flood is rate-limited, and a
stop withdraws the liveliness token, refuses new commands and closes cleanly."""

from __future__ import annotations

import json
import socket
import subprocess
import sys
from pathlib import Path
from typing import Any

from .conftest import (
    free_port,
    pamd_cli,
    rig_config,
    wait_listening,
    wait_ready,
    wait_until,
)


def test_a_taken_endpoint_refuses_before_anything_moves(tmp_path: Path) -> None:
    with socket.socket() as holder:  # someone else has the port
        holder.bind(("127.0.0.1", 0))
        holder.listen()
        port = holder.getsockname()[1]
        cfg = rig_config(tmp_path, port, recording={"dir": str(tmp_path / "rec")})
        r = subprocess.run([sys.executable, "-m", "pamd", "run", "--config", str(cfg),
                            "--duration", "5"], capture_output=True, text=True, timeout=120)
    assert r.returncode != 0
    assert f"cannot listen on tcp/127.0.0.1:{port}: the address is in use" in r.stderr
    assert "--no-telemetry" in r.stderr and "Traceback" not in r.stderr
    # nothing opened, written or recorded
    assert "STARTING" not in r.stderr and "safe outputs saved" not in r.stderr
    assert not (tmp_path / "rec").exists() or not any((tmp_path / "rec").iterdir())
    # and --no-telemetry runs on the same config
    r = subprocess.run([sys.executable, "-m", "pamd", "run", "--config", str(cfg),
                        "--duration", "0.3", "--no-telemetry", "--no-record", "--json"],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    assert json.loads(r.stdout)["telemetry"] is None


def test_clients_say_when_no_daemon_answers(tmp_path: Path, daemons: Any) -> None:
    port = free_port()
    r = pamd_cli("status", "--connect", f"tcp/127.0.0.1:{port}")
    assert r.returncode == 7 and f"cannot connect to tcp/127.0.0.1:{port}" in r.stderr
    # a router with nobody behind it: connected, but no daemon
    conf = tmp_path / "router.json5"
    conf.write_text(json.dumps({"mode": "router", "listen": {"endpoints": [
        f"tcp/127.0.0.1:{port}"]}, "scouting": {"multicast": {"enabled": False},
                                                 "gossip": {"enabled": False}}}))
    router = subprocess.Popen([sys.executable, "-m", "pamd", "router", "--zenoh-config",
                               str(conf)], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                              text=True)
    try:
        wait_listening(port)
        ep = f"tcp/127.0.0.1:{port}"
        r = pamd_cli("status", "--connect", ep)
        assert r.returncode == 7 and "no pamd daemon is alive" in r.stderr, r.stderr
        r = pamd_cli("cmd", "--connect", ep, "--rig", "sim", "--timeout", "1", "hold")
        assert r.returncode == 7 and "no answer on pamd/sim/cmd/hold" in r.stderr, r.stderr
        r = pamd_cli("watch", "--connect", ep, "--rig", "sim", "--duration", "0.5")
        assert r.returncode == 7 and "no state received" in r.stderr, r.stderr
    finally:
        router.terminate()
        out, _err = router.communicate(timeout=30)
    assert router.returncode == 0 and "pamd router: stopped" in out


def test_flood_is_rate_limited_and_stop_is_clean(tmp_path: Path, daemons: Any,
                                                agents: Any) -> None:
    port = free_port()
    cfg = rig_config(tmp_path, port, control={"slew_limit_bar_per_s": 0.25},
                     telemetry={"command_rate_per_s": 2.0, "command_burst": 5})
    d = daemons("--config", cfg)
    wait_listening(port, d)
    a = agents("--connect", f"tcp/127.0.0.1:{port}")
    wait_ready(a, "sim", d)
    a.call("subscribe", name="ev", key="pamd/sim/events")
    counts = a.call("flood", rig="sim", verb="pause", n=40)
    assert counts["rate_limited"] > 0 and counts["ok"] == 0, counts
    assert 5 <= counts["other"] < 40, counts  # the first ones reach the loop (and are refused)
    got = a.call("until", name="ev", kind="command", contains="rate limited", seconds=10)
    assert got["met"], got  # the first refusal of a flood is recorded and published
    st = a.call("status", rig="sim")
    assert st["ok"] and st["io"]["rate_limited"] == counts["rate_limited"]

    # a slow ramp, so that the stop takes a while
    verdicts: list[dict[str, Any]] = []
    wait_until(lambda: verdicts.append(a.call("cmd", rig="sim", verb="setpoint", payload={
        "muscle": "m1", "bar": 0.8, "ramp_s": 4.0})) or verdicts[-1].get("ok"), 30,
        "the setpoint taken")
    a.call("subscribe", name="st", key="pamd/sim/state/m1")
    assert a.call("until", name="st", field="setpoint_bar", above=0.7, seconds=30)["met"]
    d.proc.send_signal(15)
    # while it ramps down: the token is gone, status says so, new commands are refused
    st = wait_until(lambda: (s := a.call("status", rig="sim")).get("stopping") and s, 30,
                    "the status to say stopping")
    assert a.call("rigs") == {"rigs": []}
    v = a.call("cmd", rig="sim", verb="hold")
    assert v.get("ok") is False and "stopping" in v.get("error", ""), v
    assert d.proc.wait(60) == 0, d.log()[-3000:]
    summary = json.loads(d.out_path.read_text())
    assert summary["stop_reason"] == "SIGTERM received" and summary["final_state"] == "IDLE"
    gone = a.call("status", rig="sim", timeout=1.0)["no_daemon"]  # its session closed with
    assert "no answer" in gone or "cannot connect" in gone  # the daemon: not reconnecting
