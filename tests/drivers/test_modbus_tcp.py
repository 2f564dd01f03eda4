"""The `modbus` driver over TCP against an emulated ADAM-6024 (pymodbus simulator
on loopback): scaling round trips through the rig's calibration, bad maps,
exception responses, timeouts, write refresh and the module's communication-safety
values (the module going away and coming back: the contract suite, test_contract.py)."""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from pamd.drivers.modbus import ModbusDriver, ModbusOptions
from pamd.drivers.modbus_map import ModbusPoint

from pamd.config import load_config
from pamd.emulate.modbus_device import EmulatedModbusDevice, serve_tcp
from pamd.emulate.testing import AioThread, emulated_dict, free_port, wait_until, write_config
from pamd.loop.devices.bindings import Rig
from pamd.loop.devices.datum_file import Calibration


class Bench:
    """An emulated module on a free port plus helpers; values in volts."""

    def __init__(self, aio: AioThread, options: ModbusOptions) -> None:
        self.aio = aio
        self.options = options
        self.shown: dict[str, float] = {}
        self.received: dict[str, float] = {}
        self.device = EmulatedModbusDevice(options, self.shown.get,
                                           self.received.__setitem__)
        self.server: Any = None
        self.start()

    def start(self) -> None:
        self.server = self.aio.run(serve_tcp(self.device, "127.0.0.1", self.options.port))

    def stop(self) -> None:
        self.aio.run(self.server.shutdown())


def rig_options(tmp_path: Path) -> tuple[ModbusOptions, Any]:
    port = free_port()
    cfg = load_config(str(write_config(tmp_path, emulated_dict(tmp_path, port, can="virtual"))))
    opts = next(d.options for d in cfg.rig.drivers if d.name == "io")
    return opts, cfg


@pytest.fixture
def drivers() -> Iterator[list[Any]]:
    made: list[Any] = []
    yield made
    for d in made:
        d.close()


def test_valve_bar_to_register_and_register_to_bar(tmp_path: Path, aio: AioThread,
                                                   drivers: list[Any]) -> None:
    opts, cfg = rig_options(tmp_path)
    bench = Bench(aio, opts)
    rig = Rig(cfg, Calibration())
    io = rig.drivers["io"]
    drivers.append(io)
    io.open(time.monotonic)
    m1 = rig.muscles[0]
    m1.valve.write_si(3.0)  # 3 bar -> 5 V on a 0-6 bar VPPM -> 2048 of 4095
    assert wait_until(lambda: bench.device.tables["holding"][10] == 2048)
    assert bench.received["ao0"] == pytest.approx(5.0, abs=1.3e-3)  # half a 12-bit LSB
    m1.valve.write_si(9.0)  # beyond the config's raw_max (10 V = 6 bar): clamped
    assert wait_until(lambda: bench.device.tables["holding"][10] == 4095)
    bench.shown["ai0"] = 4.2  # the pressure sensor shows 4.2 V = 4.2 bar
    bench.shown["ai2"] = 1.5  # the load-cell amplifier 1.5 V = 300 N
    assert wait_until(lambda: abs(m1.pressure.read_si()[0] - 4.2) < 1e-3)
    assert m1.force.read_si()[0] == pytest.approx(300.0, abs=0.1)
    m1.exhaust.write_si(1.0)
    assert wait_until(lambda: bench.device.tables["coil"][16] == 1)
    stamp = m1.pressure.read_si()[1]
    assert wait_until(lambda: m1.pressure.read_si()[1] > stamp)  # stamps advance
    h = io.health()
    assert h.ok and h.counters["reads"] > 0 and h.counters["writes"] >= 3


def test_nothing_is_written_before_the_loop_writes(tmp_path: Path, aio: AioThread,
                                                   drivers: list[Any]) -> None:
    opts, _ = rig_options(tmp_path)
    bench = Bench(aio, opts)
    bench.device.tables["holding"][10] = 1234  # what the module holds at power-up
    d = ModbusDriver("io", opts)
    drivers.append(d)
    d.open(time.monotonic)
    assert wait_until(lambda: d.health().counters.get("reads", 0) > 20)
    assert bench.device.tables["holding"][10] == 1234
    assert d.health().counters.get("writes", 0) == 0


def test_unchanged_outputs_are_refreshed(tmp_path: Path, aio: AioThread,
                                         drivers: list[Any]) -> None:
    opts, _ = rig_options(tmp_path)
    opts = dataclasses.replace(opts, write_refresh_s=0.05)
    Bench(aio, opts)
    d = ModbusDriver("io", opts)
    drivers.append(d)
    d.open(time.monotonic)
    d.write(0, 2.0)
    assert wait_until(lambda: d.health().counters.get("writes", 0) >= 5)


def test_bad_address_is_counted_named_and_faults(tmp_path: Path, aio: AioThread,
                                                 drivers: list[Any]) -> None:
    opts, _ = rig_options(tmp_path)
    Bench(aio, opts)
    bad = dataclasses.replace(opts, inputs=opts.inputs + (
        ModbusPoint(name="ai9", function="holding", address=50),), fault_after_s=0.2)
    d = ModbusDriver("io", bad)
    drivers.append(d)
    d.open(time.monotonic)
    assert wait_until(lambda: d.fault is not None)
    assert "ai9" in d.fault and "illegal data address" in d.fault and "'io'" in d.fault
    h = d.health()
    assert h.counters["exception.2"] > 0 and h.counters["errors.ai9"] > 0
    assert any("ai9" in e for e in h.errors)
    assert not math.isnan(d.in_values[0])  # the good block is still read
    assert math.isnan(d.in_values[3])  # the bad channel never got a value (stale)


def test_wrong_count_for_the_device(tmp_path: Path, aio: AioThread,
                                    drivers: list[Any]) -> None:
    """A float32 map on a single-register channel reads past the device's map."""
    opts, _ = rig_options(tmp_path)
    Bench(aio, opts)
    bad = dataclasses.replace(opts, inputs=(
        ModbusPoint(name="wide", function="holding", address=2, type="float32"),))
    d = ModbusDriver("io", bad)
    drivers.append(d)
    d.open(time.monotonic)
    assert wait_until(lambda: d.health().counters.get("errors.wide", 0) > 3)


def test_timeouts_then_recovery(tmp_path: Path, aio: AioThread, drivers: list[Any]) -> None:
    opts, _ = rig_options(tmp_path)
    bench = Bench(aio, opts)
    d = ModbusDriver("io", dataclasses.replace(opts, timeout_s=0.05, fault_after_s=0.2))
    drivers.append(d)
    d.open(time.monotonic)
    assert wait_until(lambda: d.health().ok)
    bench.device.hang_s = 0.3  # the module stops answering
    assert wait_until(lambda: d.fault is not None)
    assert d.health().counters.get("timeouts", 0) + d.health().counters.get("link_errors", 0)
    stamp = d.in_stamps_s[0]
    assert wait_until(lambda: time.monotonic() - stamp > 0.2)  # stale: stamps stopped
    bench.device.hang_s = 0.0
    assert wait_until(lambda: d.fault is None and d.in_stamps_s[0] > stamp)


def test_comm_safety_values_and_watchdog(tmp_path: Path, aio: AioThread,
                                         drivers: list[Any]) -> None:
    opts, _ = rig_options(tmp_path)
    bench = Bench(aio, opts)
    d = ModbusDriver("io", opts)
    drivers.append(d)
    d.open(time.monotonic)
    assert wait_until(lambda: bench.device.tables["holding"][400] == 5)  # 0.5 s in 0.1 s
    d.write(0, 8.0)  # running at 4.8 bar
    d.write(2, 0.0)
    d.set_safe_outputs({0: 2.5, 1: 1.0, 2: 0.0, 3: 1.0})  # 1.5 bar safe pressure on m1
    assert wait_until(lambda: bench.device.safe_value("ao0") == pytest.approx(2.5, abs=0.01))
    assert wait_until(lambda: bench.device.safe_value("do1") == 1.0)
    d.set_safe_outputs({0: 3.0, 1: 1.0, 2: 0.0, 3: 1.0})  # the load changed
    assert wait_until(lambda: bench.device.safe_value("ao0") == pytest.approx(3.0, abs=0.01))
    assert wait_until(lambda: bench.device.output_value("ao0") == pytest.approx(8.0, abs=0.01))
    d.close()  # the PC goes silent
    assert wait_until(lambda: bench.device.tripped)
    assert bench.device.output_value("ao0") == pytest.approx(3.0, abs=0.01)
    assert bench.received["ao0"] == pytest.approx(3.0, abs=0.01)
    assert bench.received["do1"] == 1.0
