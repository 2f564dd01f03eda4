"""python-can's socketcand client on a driver's thread (drivers/socketcand_link.py):
a server that answers once and then refuses, or one that accepts and never speaks,
is a fault found in a fraction of a second, never a thread spinning on a core (python-
can retries a refused connect for 10 s without a pause: 8.6 s of CPU measured) or
hung on a greeting that never comes. Loopback only."""

from __future__ import annotations

import os
import socket
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from pamd.drivers.can_frames import EncoderNode
from pamd.drivers.canopen_encoder import CanEncoderDriver, CanEncoderOptions

from pamd.emulate.testing import wait_until


def _thread_cpu_s(name: str) -> float:
    """CPU time of this process's thread `name` so far (Linux: /proc)."""
    for t in threading.enumerate():
        if t.name == name and t.native_id is not None:
            stat = Path(f"/proc/self/task/{t.native_id}/stat").read_text()
            fields = stat.rsplit(")", 1)[1]
            utime, stime = fields.split()[11:13]
            return (int(utime) + int(stime)) / os.sysconf("SC_CLK_TCK")
    raise AssertionError(f"no thread {name}")


@pytest.fixture
def listener() -> Iterator[socket.socket]:
    srv = socket.create_server(("127.0.0.1", 0))
    yield srv
    srv.close()


def _driver(port: int) -> CanEncoderDriver:
    d = CanEncoderDriver("dut", CanEncoderOptions(
        interface="socketcand", host="127.0.0.1", port=port, channel="can0",
        fault_after_s=0.1, connect_timeout_s=0.2,
        encoders=(EncoderNode(name="pos", node_id=5, heartbeat_ms=20),)))
    d.open(time.monotonic)
    return d


def test_a_server_that_answers_once_then_refuses_is_a_fault_not_a_spinning_thread(
        listener: socket.socket) -> None:
    port = listener.getsockname()[1]
    accepted: list[socket.socket] = []

    def answer_once_then_go() -> None:  # a server restarting: up a moment, then gone
        conn, _ = listener.accept()
        accepted.append(conn)
        listener.close()
        conn.close()

    threading.Thread(target=answer_once_then_go, daemon=True).start()
    d = _driver(port)
    try:
        cpu0 = _thread_cpu_s("pamd-drv-dut")
        assert wait_until(lambda: d.fault is not None, timeout_s=2.0), d.health()
        assert "cannot open the bus: socketcand server 127.0.0.1" in d.fault  # type: ignore[operator]
        time.sleep(1.0)  # retrying, backing off
        assert _thread_cpu_s("pamd-drv-dut") - cpu0 < 0.3
        assert d.health().counters["bus_open_failures"] >= 2
    finally:
        d.close()


def test_a_server_that_never_greets_is_a_fault_and_the_thread_still_ends(
        listener: socket.socket) -> None:
    """It accepts (the kernel does, into its backlog) and says nothing."""
    d = _driver(listener.getsockname()[1])
    try:
        assert wait_until(lambda: d.fault is not None, timeout_s=2.0), d.health()
        assert "timed out" in d.fault  # type: ignore[operator]
    finally:
        d.close()
    assert wait_until(lambda: not [t for t in threading.enumerate()
                                   if t.is_alive() and t.name == "pamd-drv-dut"], 3.0)
