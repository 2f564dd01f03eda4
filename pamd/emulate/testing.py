"""Helpers for tests and benchmarks of the drivers and the emulated rig: free
loopback ports, an asyncio loop in a thread for emulated devices, polling waits
(generous timeouts instead of timing asserts), and variants of
config/rig-emulated.yaml on free ports (or private pty paths)."""

from __future__ import annotations

import asyncio
import contextlib
import json
import os
import random
import signal
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Coroutine
from pathlib import Path
from typing import TypeVar

import yaml

from pamd.wire.declare.jsonsafe import JsonObject, JsonValue

REPO = Path(__file__).resolve().parents[2]
RIG_EMULATED = REPO / "config" / "rig-emulated.yaml"
RIG_NIDAQ_EMULATED = REPO / "config" / "rig-nidaq-emulated.yaml"
_T = TypeVar("_T")


#: Where Linux takes the local port of every outgoing connection (and of bind(0)).
EPHEMERAL_RANGE_FILE = Path("/proc/sys/net/ipv4/ip_local_port_range")
#: Ports pamd itself defaults to (socketcand's), never handed out.
DEFAULT_PORTS = frozenset({29536})
_handed_out: set[int] = set()
_pick = random.Random()  # seeded from the OS: the suite's workers pick apart


def _ports_below_ephemeral() -> range:
    try:
        low = int(EPHEMERAL_RANGE_FILE.read_text().split()[0])
    except (OSError, ValueError, IndexError):
        return range(0)  # not Linux: bind(0) below
    return range(max(1024, low - 12000), low)


def free_port() -> int:
    """A loopback TCP port that nothing holds now, for a server started next, and not
    handed out before in this process. Chosen below the kernel's ephemeral range: a port
    from bind(0) comes from that range, where every outgoing connection on the machine
    (a test's Zenoh clients, its daemons' links) takes its own local port, and one such
    connect between this check and the server's bind made a Modbus emulator fail to
    listen on a busy machine."""
    ports = _ports_below_ephemeral()
    for _ in range(1000):
        port = _pick.choice(ports) if ports else 0
        if port in _handed_out or port in DEFAULT_PORTS:
            continue
        with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
            try:
                s.bind(("127.0.0.1", port))
            except OSError:
                continue  # held: another
            port = int(s.getsockname()[1])
        if port not in _handed_out:
            _handed_out.add(port)
            return port
    raise RuntimeError("no free loopback TCP port found in 1000 tries")


def wait_until(pred: Callable[[], object], timeout_s: float = 10.0, step_s: float = 0.01) -> bool:
    """Poll `pred` until it is true or the (generous) timeout passes."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if pred():
            return True
        time.sleep(step_s)
    return bool(pred())


class AioThread:
    """An asyncio loop on its own thread; `run(coro)` waits for the result."""

    def __init__(self) -> None:
        self.loop = asyncio.new_event_loop()
        self.thread = threading.Thread(target=self.loop.run_forever, daemon=True)
        self.thread.start()

    def run(self, coro: Coroutine[object, object, _T], timeout_s: float = 10.0) -> _T:
        return asyncio.run_coroutine_threadsafe(coro, self.loop).result(timeout_s)

    def stop(self) -> None:
        async def cancel_all() -> None:
            me = asyncio.current_task()
            for task in asyncio.all_tasks():
                if task is not me:
                    task.cancel()

        with contextlib.suppress(Exception):
            self.run(cancel_all())
        self.loop.call_soon_threadsafe(self.loop.stop)
        self.thread.join(5.0)


def emulated_dict(tmp: Path, port: int, can: str | None = None, links: str = "socket",
                  **changes: JsonValue) -> JsonObject:
    """config/rig-emulated.yaml on `port` (its Modbus TCP module; its other links on
    other free ports), real-time settings off. `links`: "socket" (the shipped loopback
    sockets: RTU frames over TCP, CAN through socketcand) or "pty" (socat pty pairs
    under `tmp`, the older links); `can` overrides the CAN link alone: "socketcand",
    "serial" (a pty), or "virtual" (the CAN bus inside one process)."""
    if links not in ("socket", "pty"):
        raise ValueError(f"links is 'socket' or 'pty', not {links!r}")
    can = can or ("socketcand" if links == "socket" else "serial")
    _handed_out.add(port)  # the Modbus module's: the other links get others
    d: JsonObject = yaml.safe_load(RIG_EMULATED.read_text())  # the YAML file's mapping
    d["loop"]["realtime"] = {"enabled": False}
    d["telemetry"] = {"enabled": False}  # tests and benches keep off the default port
    for drv in d["drivers"]:
        o = drv["options"]
        if drv["type"] == "modbus" and o["transport"] == "tcp":
            o["port"] = port
        elif drv["type"] == "modbus" and links == "pty":
            o.pop("host", None)
            o.pop("port", None)
            o.update(transport="rtu", serial_port=str(tmp / "rtu"))
        elif drv["type"] == "modbus":
            o["port"] = free_port()
        elif drv["type"] == "canopen-encoder":
            o.pop("host", None)
            o.pop("port", None)
            o["interface"] = can
            if can == "socketcand":
                o.update(host="127.0.0.1", port=free_port(), channel="can0")
            else:
                o["channel"] = str(tmp / "can") if can == "serial" else f"pamd-test-{port}"
    for k, v in changes.items():
        d[k] = v
    return d


def nidaq_emulated_dict(port: int, **changes: JsonValue) -> JsonObject:
    """config/rig-nidaq-emulated.yaml with its NI gRPC Device Server on `port`,
    real-time settings and telemetry off, and the patience of a test beside others on
    a busy machine (a sample up to 0.3 s late is not stale: staleness is not tested)."""
    _handed_out.add(port)
    d: JsonObject = yaml.safe_load(RIG_NIDAQ_EMULATED.read_text())  # the YAML file's mapping
    d["loop"]["realtime"] = {"enabled": False}
    d["safety"]["latency_margin_s"] = 0.3
    d["telemetry"] = {"enabled": False}
    for drv in d["drivers"]:
        if drv["type"] == "nidaqmx":
            drv["options"]["server"] = f"127.0.0.1:{port}"
    for k, v in changes.items():
        d[k] = v
    return d


def write_config(tmp: Path, data: JsonObject, name: str = "rig.yaml") -> Path:
    path = tmp / name
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def start_emulator(config_path: str, *extra: str
                   ) -> tuple[subprocess.Popen[str], JsonObject]:
    """`pamd emulate --config FILE` in its own process; returns (process, ready line)."""

    env = dict(os.environ, PYTHONUNBUFFERED="1")
    proc = subprocess.Popen([sys.executable, "-m", "pamd", "emulate", "--config", config_path,
                             *extra], stdout=subprocess.PIPE, stderr=subprocess.DEVNULL,
                            text=True, env=env)
    assert proc.stdout is not None
    line = proc.stdout.readline()
    if not line:
        proc.wait(10)
        raise RuntimeError(f"pamd emulate exited ({proc.returncode}) before it was ready")
    return proc, json.loads(line)


def stop_emulator(proc: subprocess.Popen[str]) -> JsonObject:
    """SIGTERM, wait, and return its closing statistics line."""

    proc.send_signal(signal.SIGTERM)
    out, _ = proc.communicate(timeout=20)
    lines = out.strip().splitlines()
    return json.loads(lines[-1]) if lines else {}
