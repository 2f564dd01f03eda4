"""Helpers of the network tests: `pamd run` as a subprocess on its own free port (real
clock, settings a busy 2-core machine cannot trip), client processes with their own
Zenoh sessions (`agent.py`, driven line by line), and polling waits, never timing
asserts."""

from __future__ import annotations

import copy
import json
import os
import select
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest
import yaml

from pamd.emulate.testing import free_port

REPO = Path(__file__).resolve().parents[2]
SIM_YAML = REPO / "config" / "sim.yaml"
AGENT = Path(__file__).with_name("agent.py")

ROBUST: dict[str, Any] = {  # real clock, nothing a busy test machine can trip
    "loop": {"rate_hz": 500, "clock": "real", "stall_timeout_s": 1.0,
             "realtime": {"enabled": False}},
    "safety": {"signal_timeout_s": 0.5, "startup_timeout_s": 3.0, "tracking_time_s": 5.0},
}


def merge(base: dict[str, Any], changes: dict[str, Any]) -> dict[str, Any]:
    out = copy.deepcopy(base)
    for k, v in changes.items():
        out[k] = merge(out[k], v) if isinstance(v, dict) and isinstance(out.get(k), dict) else v
    return out


def rig_config(tmp: Path, port: int | None, name: str = "rig.yaml", **changes: Any) -> Path:
    """config/sim.yaml on the real clock, telemetry on 127.0.0.1:`port`."""
    data = merge(yaml.safe_load(SIM_YAML.read_text()), ROBUST)
    if port is not None:
        data = merge(data, {"telemetry": {"listen": f"tcp/127.0.0.1:{port}"}})
    data = merge(data, changes)
    path = tmp / name
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def wait_until(pred: Callable[[], Any], timeout_s: float = 30.0, what: str = "") -> Any:
    deadline = time.monotonic() + timeout_s
    got = None
    while time.monotonic() < deadline:
        got = pred()
        if got:
            return got
        time.sleep(0.05)
    pytest.fail(f"timed out after {timeout_s:g} s waiting for {what} (last: {got!r:.300})")


class DaemonProc:
    """`python -m pamd run --json ARGS` with stdout and stderr in files."""

    def __init__(self, tmp: Path, args: list[str], name: str = "pamd") -> None:
        self.out_path, self.err_path = tmp / f"{name}.out", tmp / f"{name}.err"
        env = dict(os.environ, PYTHONUNBUFFERED="1", OPENBLAS_NUM_THREADS="1")
        for k in ("NOTIFY_SOCKET", "WATCHDOG_USEC", "WATCHDOG_PID"):
            env.pop(k, None)
        if "--duration" not in args:  # a daemon a test loses track of stops by itself
            args = [*args, "--duration", "600"]
        if "--end-on-fault" not in args:  # it stands in for the service: a fault waits
            args = [*args, "--stay-on-fault"]  # for a reset (a run with an end would end)
        with open(self.out_path, "w") as out, open(self.err_path, "w") as err:
            self.proc = subprocess.Popen([sys.executable, "-m", "pamd", "run", "--json", *args],
                                         stdout=out, stderr=err, env=env, cwd=tmp)

    def log(self) -> str:
        return self.err_path.read_text()

    def summary(self) -> dict[str, Any]:
        return json.loads(self.out_path.read_text())

    def stop(self, timeout_s: float = 60.0) -> int:
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
        return self.proc.wait(timeout_s)


class Agent:
    """A client process (agent.py): `call(op, **fields)` -> its JSON answer."""

    def __init__(self, *args: str) -> None:
        self.proc = subprocess.Popen([sys.executable, str(AGENT), *args], stdin=subprocess.PIPE,
                                     stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                     env=dict(os.environ, OPENBLAS_NUM_THREADS="1"))
        self._buf = b""
        self.hello = self._line(30.0)

    def _line(self, timeout_s: float) -> Any:
        assert self.proc.stdout is not None
        fd = self.proc.stdout.fileno()
        deadline = time.monotonic() + timeout_s
        while b"\n" not in self._buf:
            left = deadline - time.monotonic()
            if left <= 0 or not select.select([fd], [], [], left)[0]:
                pytest.fail(f"the client process gave no answer within {timeout_s:g} s")
            chunk = os.read(fd, 65536)
            if not chunk:
                err = self.proc.stderr.read().decode() if self.proc.stderr else ""
                pytest.fail(f"the client process ended: {err[-2000:]}")
            self._buf += chunk
        line, self._buf = self._buf.split(b"\n", 1)
        return json.loads(line)

    def call(self, op: str, timeout_s: float = 60.0, **fields: Any) -> Any:
        assert self.proc.stdin is not None
        self.proc.stdin.write((json.dumps({"op": op, **fields}) + "\n").encode())
        self.proc.stdin.flush()
        return self._line(timeout_s)

    def close(self) -> None:
        if self.proc.poll() is None:
            assert self.proc.stdin is not None
            self.proc.stdin.close()
            try:
                self.proc.wait(10)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait(5)


@pytest.fixture
def agents() -> Iterator[Callable[..., Agent]]:
    made: list[Agent] = []

    def make(*args: str) -> Agent:
        a = Agent(*args)
        made.append(a)
        return a

    yield make
    for a in made:
        a.close()


@pytest.fixture
def daemons(tmp_path: Path) -> Iterator[Callable[..., DaemonProc]]:
    made: list[DaemonProc] = []

    def make(*args: str | Path, name: str = "pamd") -> DaemonProc:
        d = DaemonProc(tmp_path, [str(a) for a in args], name)
        made.append(d)
        return d

    yield make
    for d in made:
        if d.proc.poll() is None:
            d.proc.kill()
            d.proc.wait(10)


def wait_ready(agent: Agent, rig: str = "sim", daemon: DaemonProc | None = None,
               timeout_s: float = 60.0) -> dict[str, Any]:
    """Until the daemon answers status in a steady state (sensors read)."""

    def ready() -> dict[str, Any] | None:
        if daemon is not None and daemon.proc.poll() is not None:
            pytest.fail(f"the daemon exited ({daemon.proc.returncode}): {daemon.log()[-3000:]}")
        st = agent.call("status", rig=rig, timeout=1.0)
        return st if st.get("ok") and st.get("state") in ("IDLE", "RUNNING") else None

    return wait_until(ready, timeout_s, "the daemon's status")


class RigProc:
    """`pamd run --record <tmp>/rec` on its own loopback port (config/sim.yaml, ROBUST,
    with `changes`) and a client process connected to it, once the daemon answers
    status in a steady state; `close()` ends both."""

    def __init__(self, tmp: Path, rig: str = "sim", args: tuple[str, ...] = (),
                 **changes: Any) -> None:
        self.tmp, self.rig = tmp, rig
        self.port = free_port()
        self.endpoint = f"tcp/127.0.0.1:{self.port}"
        self.rec = tmp / "rec"
        cfg = rig_config(tmp, self.port, **changes)
        self.daemon = DaemonProc(tmp, ["--config", str(cfg), "--record", str(self.rec),
                                       *args])
        try:
            wait_listening(self.port, self.daemon)
            self.agent = Agent("--connect", self.endpoint)
            assert self.agent.hello.get("ready"), self.agent.hello
            self.zid = self.agent.hello["zid"]
            self.status0 = wait_ready(self.agent, rig, self.daemon)
        except BaseException:
            self.daemon.proc.kill()
            self.daemon.proc.wait(10)
            raise

    def status(self) -> dict[str, Any]:
        return self.agent.call("status", rig=self.rig)

    def cmd(self, verb: str, payload: Any = None, **kw: Any) -> dict[str, Any]:
        return self.agent.call("cmd", rig=self.rig, verb=verb, payload=payload or {}, **kw)

    def close(self) -> None:
        self.agent.close()
        if self.daemon.proc.poll() is None:
            self.daemon.proc.kill()
            self.daemon.proc.wait(10)


def wait_listening(port: int, daemon: DaemonProc | None = None,
                   timeout_s: float = 60.0) -> None:
    """Until something accepts TCP connections on 127.0.0.1:`port`."""

    def up() -> bool:
        if daemon is not None and daemon.proc.poll() is not None:
            pytest.fail(f"the daemon exited ({daemon.proc.returncode}): {daemon.log()[-3000:]}")
        with socket.socket() as s:
            s.settimeout(1.0)
            return s.connect_ex(("127.0.0.1", port)) == 0

    wait_until(up, timeout_s, f"a listener on port {port}")


def pamd_cli(*args: str, timeout_s: float = 60.0) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "pamd", *args], capture_output=True, text=True,
                          timeout=timeout_s, env=dict(os.environ, OPENBLAS_NUM_THREADS="1"))
