"""The `modbus` driver over RTU (115200 baud) against an emulated load-cell
transmitter on a socat pty pair: float32 scaling, int32 word order, a coil write and
garbage on the line (the port vanishing and coming back: test_contract.py)."""

from __future__ import annotations

import os
import time
from pathlib import Path

import pytest
from pamd.drivers.modbus import ModbusDriver, ModbusOptions
from pamd.drivers.modbus_map import ModbusPoint

from pamd.emulate.modbus_device import EmulatedModbusDevice, serve_rtu
from pamd.emulate.ptys import PtyPair
from pamd.emulate.testing import AioThread, wait_until

pytestmark = pytest.mark.usefixtures("socat")  # missing: fails saying so


def options(port: str) -> ModbusOptions:
    return ModbusOptions(
        transport="rtu", serial_port=port, baud=115200, device_id=7, timeout_s=0.05,
        poll_period_s=0.0, fault_after_s=0.2, reconnect_max_s=0.2,
        inputs=(ModbusPoint(name="force", function="input", address=0, type="float32",
                            unit="N"),
                ModbusPoint(name="count", function="input", address=2, type="int32",
                            word_order="little", unit="")),
        outputs=(ModbusPoint(name="tare", function="coil", address=0, unit=""),))


def test_rtu_round_trip_and_garbage(tmp_path: Path, aio: AioThread) -> None:
    host = str(tmp_path / "rtu")
    shown: dict[str, float] = {"force": 294.3, "count": -7}
    got: dict[str, float] = {}
    opts = options(host)
    dev = EmulatedModbusDevice(opts, shown.get, got.__setitem__)
    pair = PtyPair(host)
    server = aio.run(serve_rtu(dev, pair.device, 115200))
    d = ModbusDriver("lc", opts)
    d.open(time.monotonic)
    try:
        assert wait_until(lambda: d.in_values[0] == pytest.approx(294.3, abs=1e-4))
        assert d.in_values[1] == -7.0
        d.write(0, 1.0)
        assert wait_until(lambda: got.get("tare") == 1.0)
        # garbage on the line: the driver counts it and carries on
        with open(pair.device, "wb", buffering=0) as raw:
            raw.write(os.urandom(64))
        assert wait_until(lambda: d.fault is None and d.health().counters["reads"] > 50)
        shown["force"] = 100.0
        assert wait_until(lambda: d.in_values[0] == pytest.approx(100.0))
        # the port vanishing and coming back: the contract suite (test_contract.py)
    finally:
        d.close()
        aio.run(server.shutdown())
        pair.close()
