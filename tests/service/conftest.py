"""Helpers of the service tests: `pamd run` as a subprocess (the way systemd runs
it) with a notify socket the test binds, configs for a busy 2-core machine (real
clock, slower loop, generous timeouts), and polling waits instead of timing
asserts."""

from __future__ import annotations

import copy
import os
import signal
import socket
import subprocess
import sys
import threading
import time
import uuid
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest
import yaml

from .testhooks import SLOW_RELOAD_ENV, STALL_ENV

#: `pamd run` with the tests' hooks (`python tests/service/testhooks.py run ...`)
HOOKS = Path(__file__).resolve().parent / "testhooks.py"

REPO = Path(__file__).resolve().parents[2]
SIM_YAML = REPO / "config" / "sim.yaml"

ROBUST: dict[str, Any] = {  # real clock, but nothing a busy test machine can trip
    "loop": {"rate_hz": 250, "clock": "real", "stall_timeout_s": 1.0,
             "realtime": {"enabled": False}},
    "safety": {"signal_timeout_s": 0.5, "startup_timeout_s": 1.5, "tracking_time_s": 3.0},
    "telemetry": {"enabled": False},  # never on the default port 7447 in tests
}


def merge(base: dict[str, Any], changes: dict[str, Any]) -> dict[str, Any]:
    out = copy.deepcopy(base)
    for k, v in changes.items():
        out[k] = merge(out[k], v) if isinstance(v, dict) and isinstance(out.get(k), dict) else v
    return out


def sim_dict(**changes: Any) -> dict[str, Any]:
    """config/sim.yaml on the real clock with ROBUST settings and `changes`."""
    return merge(merge(yaml.safe_load(SIM_YAML.read_text()), ROBUST), changes)


def write_yaml(path: Path, data: dict[str, Any]) -> Path:
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def wait_until(pred: Callable[[], Any], timeout_s: float = 30.0, step_s: float = 0.02) -> bool:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if pred():
            return True
        time.sleep(step_s)
    return bool(pred())


class NotifySocket:
    """What systemd would receive: a datagram socket on an abstract name ('@...'),
    every message kept with its arrival time."""

    def __init__(self) -> None:
        self.name = f"@pamd-test-{uuid.uuid4().hex}"
        self.sock = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
        self.sock.bind(b"\0" + self.name[1:].encode())
        self.sock.settimeout(0.1)
        self.messages: list[tuple[float, str]] = []
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._recv, daemon=True)
        self._thread.start()

    def _recv(self) -> None:
        while not self._stop.is_set():
            try:
                data = self.sock.recv(65536)
            except TimeoutError:
                continue
            except OSError:
                return
            self.messages.append((time.monotonic(), data.decode()))

    def env(self, watchdog_usec: int | None = None) -> dict[str, str]:
        env = {"NOTIFY_SOCKET": self.name}
        if watchdog_usec is not None:
            env["WATCHDOG_USEC"] = str(watchdog_usec)
        return env

    def texts(self) -> list[str]:
        return [m for _t, m in list(self.messages)]

    def index(self, line: str) -> int:
        """Index of the first message with `line` as one of its lines (-1: none)."""
        for i, m in enumerate(self.texts()):
            if line in m.split("\n"):
                return i
        return -1

    def count(self, line: str) -> int:
        return sum(1 for m in self.texts() if line in m.split("\n"))

    def ping_times(self) -> list[float]:
        return [t for t, m in list(self.messages) if "WATCHDOG=1" in m.split("\n")]

    def statuses(self) -> list[str]:
        return [ln[len("STATUS="):] for m in self.texts() for ln in m.split("\n")
                if ln.startswith("STATUS=")]

    def close(self) -> None:
        self._stop.set()
        self._thread.join(2.0)
        self.sock.close()


class DaemonProcess:
    """`python -m pamd run ARGS` with its stdout and stderr in files."""

    def __init__(self, tmp: Path, args: list[str], env: dict[str, str] | None = None,
                 name: str = "pamd") -> None:
        self.out_path = tmp / f"{name}.out"
        self.err_path = tmp / f"{name}.err"
        full_env = dict(os.environ, PYTHONUNBUFFERED="1", OPENBLAS_NUM_THREADS="1")
        for k in ("NOTIFY_SOCKET", "WATCHDOG_USEC", "WATCHDOG_PID"):
            full_env.pop(k, None)
        full_env.update(env or {})
        # a test hook asked for: `pamd run` through the hooks' launcher (tests/service/
        # testhooks.py: the hooks are the tests', not pamd's)
        hooked = any(k in full_env for k in (STALL_ENV, SLOW_RELOAD_ENV))
        pamd = [str(HOOKS)] if hooked else ["-m", "pamd"]
        with open(self.out_path, "w") as out, open(self.err_path, "w") as err:
            self.proc = subprocess.Popen([sys.executable, *pamd, "run", *args],
                                         stdout=out, stderr=err, env=full_env, cwd=tmp)

    def log(self) -> str:
        return self.err_path.read_text()

    def stdout(self) -> str:
        return self.out_path.read_text()

    def wait_log(self, text: str, timeout_s: float = 30.0) -> bool:
        """Until `text` is in the log (False if the process ends without it)."""
        wait_until(lambda: text in self.log() or self.proc.poll() is not None, timeout_s)
        return text in self.log()

    def until(self, pred: Callable[[], Any], timeout_s: float = 30.0) -> bool:
        """Wait for `pred` while the process runs (a process that died fails fast)."""
        wait_until(lambda: pred() or self.proc.poll() is not None, timeout_s)
        return bool(pred())

    def send(self, sig: int) -> None:
        self.proc.send_signal(sig)

    def finish(self, timeout_s: float = 90.0) -> int:
        """SIGTERM (if still running) and the exit code."""
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
        return self.proc.wait(timeout_s)


@pytest.fixture
def notify() -> Iterator[NotifySocket]:
    s = NotifySocket()
    yield s
    s.close()


@pytest.fixture
def pamd_run(tmp_path: Path) -> Iterator[Callable[..., DaemonProcess]]:
    """Start `pamd run` subprocesses; any still running at the end are killed."""
    made: list[DaemonProcess] = []

    def start(*args: str | Path, env: dict[str, str] | None = None,
              name: str = "pamd") -> DaemonProcess:
        p = DaemonProcess(tmp_path, [str(a) for a in args], env, name)
        made.append(p)
        return p

    yield start
    for p in made:
        if p.proc.poll() is None:
            p.proc.kill()
            p.proc.wait(10)
