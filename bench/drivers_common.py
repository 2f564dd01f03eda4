"""Shared by the drivers_* benchmarks: run the daemon on a config for a while, or
through one profile, and return its summary (`Daemon.result()`)."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import _lockdir  # noqa: F401  (the run's own rig-lock directory)
import yaml

from pamd.config import load_config
from pamd.daemon.daemon import Daemon
from pamd.emulate.testing import REPO, emulated_dict, free_port, write_config
from pamd.wire.tick import State


def sim_config(tmp: Path, realtime: bool = True) -> Any:
    d = yaml.safe_load((REPO / "config" / "sim.yaml").read_text())
    d["loop"]["realtime"] = {"enabled": realtime}
    return load_config(str(write_config(tmp, d, "sim.yaml")))


def emulated_config(tmp: Path, realtime: bool = True) -> Any:
    d = emulated_dict(tmp, free_port())
    d["loop"]["realtime"] = {"enabled": realtime}
    return load_config(str(write_config(tmp, d, "rig-emulated.yaml")))


def run_idle(cfg: Any, seconds: float) -> dict[str, Any]:
    daemon = Daemon(cfg)
    daemon.start(seconds)
    try:
        daemon.wait()
    finally:
        daemon.stop("bench")
        daemon.wait(timeout_s=40)
        daemon.close()
    return daemon.result()


def run_profile(cfg: Any, profile: dict[str, Any],
                lengths_mm: dict[str, float] | None = None) -> dict[str, Any]:
    """Start, home (if lengths are given), run `profile` to its end, stop."""
    daemon = Daemon(cfg)
    daemon.start()
    try:
        st = daemon.wait_for_state((State.IDLE, State.FAULT), 20)
        if st != State.IDLE:
            raise RuntimeError(f"the rig did not start: {daemon.ctrl.supervisor.reason}")
        for m, length in (lengths_mm or {}).items():
            v = daemon.command("home", {"muscle": m, "length_mm": length})
            if not v["ok"]:
                raise RuntimeError(v["error"])
        v = daemon.command("profile", profile)
        if not v["ok"]:
            raise RuntimeError(v["error"])
        time.sleep(0.5)
        daemon.wait_for_state((State.IDLE, State.FAULT, State.ESTOP),
                              (v.get("duration_s") or 60.0) + 30.0)
    finally:
        daemon.stop("bench")
        daemon.wait(timeout_s=40)
        daemon.close()
    return daemon.result()
