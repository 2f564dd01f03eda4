"""The `modbus` driver over RTU when replies go missing: a serial proxy between the
driver and the emulated load-cell transmitter (two socat pty pairs) swallows requests,
so the device never answers them (to the master, a lost request and a lost reply are
the same unanswered request).

Both ways: one lost reply costs one retry (no reconnect, no driver fault); a dead
device (the port still open, nothing answering) is still found, within `fault_after_s`
plus one request timeout, counted in its own waits (not in wall-clock time, which a
busy machine stretches). And the config loader refuses a request timeout that one
lost reply would carry past its signal's timeout.
"""

from __future__ import annotations

import math
import os
import select
import threading
import time
from pathlib import Path

import pytest
from pamd.drivers.modbus import ModbusDriver, ModbusOptions
from pamd.drivers.modbus_map import ModbusPoint

from pamd.config.loader import load_config
from pamd.emulate.modbus_device import EmulatedModbusDevice, serve_rtu
from pamd.emulate.ptys import PtyPair
from pamd.emulate.testing import AioThread, emulated_dict, free_port, wait_until, write_config
from pamd.wire.errors import ConfigError

pytestmark = pytest.mark.usefixtures("socat")  # missing: fails saying so

# Far above what the pty pairs' delivery takes on a busy machine (measured up to 665 ms
# beside CPU hogs, bench/pty_delivery.py): only the proxy's drops go unanswered; what is
# tested is the driver's logic (retry, not reconnect; the fault's time), not its speed.
TIMEOUT_S = 1.0
FAULT_AFTER_S = 3.0


class DroppingProxy(threading.Thread):
    """Copies bytes between the driver's line and the device's line; swallows the next
    `drop_next` requests (a request: the bytes the driver sends in one burst), or all
    of them while `drop_all` is set."""

    BURST_S = 0.05  # the bytes of one request arrive within this of each other (a pty
    # may split them; the driver sends its next request a reply or TIMEOUT_S later)

    def __init__(self, driver_side: str, device_side: str) -> None:
        super().__init__(daemon=True)
        flags = os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK
        self.a = os.open(driver_side, flags)
        self.b = os.open(device_side, flags)
        self.drop_next = 0
        self.drop_all = False
        self.dropped = 0
        self.forwarded = 0
        self.stopping = threading.Event()
        self._lock = threading.Lock()

    def drop(self, n: int) -> None:
        with self._lock:
            self.drop_next += n

    def _read(self, fd: int) -> bytes:
        try:
            return os.read(fd, 4096)
        except (BlockingIOError, OSError):
            return b""

    def run(self) -> None:
        while not self.stopping.is_set():
            ready, _, _ = select.select([self.a, self.b], [], [], 0.05)
            if self.b in ready and (data := self._read(self.b)):
                os.write(self.a, data)
            if self.a not in ready or not (data := self._read(self.a)):
                continue
            with self._lock:
                swallow = self.drop_all or self.drop_next > 0
                if swallow and not self.drop_all:
                    self.drop_next -= 1
            if not swallow:
                os.write(self.b, data)
                self.forwarded += 1
                continue
            while select.select([self.a], [], [], self.BURST_S)[0]:  # the rest of it
                self._read(self.a)
            self.dropped += 1

    def close(self) -> None:
        self.stopping.set()
        self.join(2.0)
        os.close(self.a)
        os.close(self.b)


class FaultWatch(ModbusDriver):
    """The driver, noting how many requests had gone unanswered when it set `fault`."""

    timeouts_at_fault: int | None = None

    def failing(self, what: str) -> None:
        super().failing(what)
        if self.fault is not None and self.timeouts_at_fault is None:
            self.timeouts_at_fault = self.counters.get("timeouts", 0)


class Line:
    """Driver -> pty pair -> proxy -> pty pair -> emulated transmitter."""

    def __init__(self, tmp: Path) -> None:
        self.opts = ModbusOptions(
            transport="rtu", serial_port=str(tmp / "rtu"), baud=115200, device_id=7,
            timeout_s=TIMEOUT_S, poll_period_s=0.0, fault_after_s=FAULT_AFTER_S,
            reconnect_max_s=0.2, lost_after=3,
            inputs=(ModbusPoint(name="force", function="input", address=0, type="float32",
                                unit="N"),))
        self.driver_pair = PtyPair(str(tmp / "rtu"))
        self.device_pair = PtyPair(str(tmp / "dev"))
        self.proxy = DroppingProxy(self.driver_pair.device, self.device_pair.host)
        self.proxy.start()
        self.aio = AioThread()
        self.device = EmulatedModbusDevice(self.opts, {"force": 294.3}.get,
                                           lambda k, v: None)
        self.server = self.aio.run(serve_rtu(self.device, self.device_pair.device, 115200))
        self.driver = FaultWatch("lc", self.opts)

    def reads(self) -> int:
        return self.driver.health().counters.get("reads", 0)

    def close(self) -> None:
        self.driver.close()
        self.aio.run(self.server.shutdown())
        self.aio.stop()
        self.proxy.close()
        self.driver_pair.close()
        self.device_pair.close()


@pytest.fixture
def line(tmp_path: Path) -> Line:
    ln = Line(tmp_path)
    yield ln  # type: ignore[misc]
    ln.close()


def test_one_lost_reply_costs_one_retry_not_a_reconnect(line: Line) -> None:
    d = line.driver
    d.open(time.monotonic)
    assert wait_until(lambda: line.reads() > 20)
    for n in (1, 2):  # two lost replies, apart: each is one retry
        line.proxy.drop(1)
        assert wait_until(lambda n=n: line.proxy.dropped == n)
        before = line.reads()
        assert wait_until(lambda before=before: line.reads() > before + 20)
    c = d.health().counters
    assert c["timeouts"] == 2 and c["retries"] == 2
    assert c.get("disconnects", 0) == 0 and c["connects"] == 1  # the link was kept
    assert d.fault is None and d.timeouts_at_fault is None and d.connected
    assert d.in_values[0] == pytest.approx(294.3, abs=1e-4)


def test_lost_replies_below_lost_after_in_a_row_are_retried(line: Line) -> None:
    d = line.driver
    d.open(time.monotonic)
    assert wait_until(lambda: line.reads() > 20)
    line.proxy.drop(2)  # lost_after 3: two in a row are still noise
    assert wait_until(lambda: line.proxy.dropped == 2)
    before = line.reads()
    assert wait_until(lambda: line.reads() > before + 20)
    c = d.health().counters
    assert c["retries"] == 2 and c.get("disconnects", 0) == 0 and d.fault is None


def test_a_dead_device_is_found_within_fault_after_plus_one_timeout(line: Line) -> None:
    d = line.driver
    d.open(time.monotonic)
    assert wait_until(lambda: line.reads() > 20)
    line.proxy.drop_all = True  # the transmitter dies; its line stays open
    assert wait_until(lambda: d.fault is not None)
    assert "no response" in d.fault.lower() and str(line.opts.serial_port) in d.fault
    # Each unanswered request waited timeout_s at least, and failure counts from the
    # first: the fault came by the request that ended fault_after_s + timeout_s after
    # the device went silent (a slower machine only lets fewer requests go by).
    assert d.timeouts_at_fault is not None
    assert d.timeouts_at_fault <= math.ceil(FAULT_AFTER_S / TIMEOUT_S) + 1
    c = d.health().counters
    assert c["timeouts"] >= 3 and c["disconnects"] >= 1  # lost_after in a row: link lost
    line.proxy.drop_all = False  # it comes back: the driver recovers by itself
    assert wait_until(lambda: d.fault is None and d.connected)


def _emulated(tmp: Path, **lc2: float) -> Path:
    d = emulated_dict(tmp, free_port())
    for drv in d["drivers"]:
        if drv["name"] == "lc2":
            drv["options"].update(lc2)
    return write_config(tmp, d)


def test_config_refuses_a_request_timeout_one_lost_reply_makes_stale(tmp_path: Path) -> None:
    # m2.force: timeout_s 0.1, sample period 0.01, margin 0.1 -> stale at 0.11 s
    load_config(str(_emulated(tmp_path, timeout_s=0.05)))  # 0.05 + 0.01 + 2.5 ms fits
    path = _emulated(tmp_path, timeout_s=0.1)
    with pytest.raises(ConfigError) as err:
        load_config(str(path))
    text = str(err.value)
    lines = path.read_text().splitlines()
    lc2 = next(i for i, ln in enumerate(lines) if "name: lc2" in ln)
    line_no = next(i for i, ln in enumerate(lines[lc2:], lc2 + 1) if "timeout_s:" in ln)
    assert f"{path}:{line_no}: drivers[1].options.timeout_s" in text
    assert "m2.force" in text and "0.11 s" in text
