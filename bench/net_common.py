"""Shared helpers of the network benchmarks: a rig config on its own port, `pamd run`
as a subprocess, waiting for it to answer."""

from __future__ import annotations

import os

import _lockdir  # noqa: F401  (the run's own rig-lock directory)

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import json  # noqa: E402
import socket  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Any  # noqa: E402

import yaml  # noqa: E402

REPO = Path(__file__).resolve().parents[1]


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def write_config(tmp: str, port: int, realtime: bool = True, loop_rate_hz: float = 1000.0,
                 **telemetry: Any) -> str:
    data = yaml.safe_load((REPO / "config" / "sim.yaml").read_text())
    data["loop"]["clock"] = "real"
    data["loop"]["rate_hz"] = loop_rate_hz
    data["loop"]["realtime"] = {"enabled": realtime}
    data["telemetry"] = {"listen": f"tcp/127.0.0.1:{port}", "command_rate_per_s": 1e6,
                         "command_burst": 100000, **telemetry}
    path = Path(tmp) / "rig.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return str(path)


def start(cfg: str, *args: str) -> subprocess.Popen[str]:
    return subprocess.Popen([sys.executable, "-m", "pamd", "run", "--config", cfg, "--json",
                             "--no-record", *args], stdout=subprocess.PIPE,
                            stderr=subprocess.DEVNULL, text=True)


def wait_listening(port: int, timeout_s: float = 60.0) -> None:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        with socket.socket() as s:
            if s.connect_ex(("127.0.0.1", port)) == 0:
                return
        time.sleep(0.05)
    raise SystemExit(f"nothing listens on port {port}")


def wait_status(client: Any, rig: str = "sim", timeout_s: float = 60.0) -> dict[str, Any]:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        try:
            st = client.status(rig, 1.0)
            if st.get("ok") and st.get("state") in ("IDLE", "RUNNING"):
                return st
        except Exception:
            pass
        time.sleep(0.1)
    raise SystemExit("the daemon does not answer")


def stop(proc: subprocess.Popen[str]) -> dict[str, Any]:
    proc.send_signal(15)
    out, _ = proc.communicate(timeout=120)
    return json.loads(out)


def pct(values: list[float], q: float) -> float:
    s = sorted(values)
    return s[min(len(s) - 1, int(q / 100 * len(s)))] if s else float("nan")


def line(name: str, values_s: list[float]) -> str:
    us = [v * 1e6 for v in values_s]
    return (f"{name:<34} n={len(us):5d}  p50 {pct(us, 50):7.0f} us  p99 {pct(us, 99):7.0f} us"
            f"  max {max(us) if us else float('nan'):7.0f} us")
