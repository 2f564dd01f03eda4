"""An emulated Modbus I/O module: the register map of a `modbus` driver's options
served by pymodbus's simulator (`SimDevice` / `SimData`) over TCP, RTU on a serial
port (one end of a pty pair) or RTU frames over TCP.

Input channels are refreshed from a value source on every request (so a read sees
the physics of that instant), or, with `sample_period_s`, once per sample period
like a module that samples slower than it is polled (its sample counter or sample-
age register, if the options name one, says which sample is served), writes to
output channels go to a value sink, and the module has a communication watchdog like
an ADAM's 'Comm Safety': when no request has arrived for the watchdog time, every
output that has a safe-value register takes that value. Addresses outside the map
answer with exception 2 (illegal data address), as a real module does. `hang_s`
makes it stop answering (timeouts) for tests.
"""

from __future__ import annotations

import asyncio
import time
from collections.abc import Callable
from typing import Protocol

from pymodbus.constants import ExcCodes
from pymodbus.simulator import DataType, SimData, SimDevice
from pymodbus.simulator.simutils import SimUtils

from pamd.drivers.modbus import ModbusOptions, effective_map
from pamd.drivers.modbus_map import ModbusPoint, decode, encode, to_raw, to_value

Source = Callable[[str], "float | None"]
Sink = Callable[[str, float], None]

_FC_READ = {1: "coil", 2: "discrete", 3: "holding", 4: "input"}
_FC_WRITE = {5: "coil", 15: "coil", 6: "holding", 16: "holding"}
_PARKING = 65000  # where an otherwise empty table gets one register (pymodbus needs one)


class EmulatedModbusDevice:
    """The register image of one module, its value source/sink and its watchdog."""

    def __init__(self, options: ModbusOptions, source: Source, sink: Sink,
                 label: str = "modbus", sample_period_s: float = 0.0) -> None:
        self.options = options
        self.label = label
        self.inputs, self.outputs = effective_map(options)
        self.source, self.sink = source, sink
        self.tables: dict[str, dict[int, int]] = {f: {} for f in
                                                  ("coil", "discrete", "holding", "input")}
        self._in_at: dict[tuple[str, int], ModbusPoint] = {}
        self._out_at: dict[tuple[str, int], ModbusPoint] = {}
        for p in self.inputs:
            for k in range(p.words):
                self.tables[p.function][p.address + k] = 0
                self._in_at[(p.function, p.address + k)] = p
        for p in self.outputs:
            for k in range(p.words):
                self.tables[p.function][p.address + k] = 0
                self._out_at[(p.function, p.address + k)] = p
            if p.safe_address is not None:
                for k in range(p.words):
                    self.tables[p.function][p.safe_address + k] = 0
        self.sample_period_s = sample_period_s
        self.samples = 0
        self._sampled_s = -float("inf")
        sc = options.sample_clock
        if sc is not None:
            self.tables[sc.function][sc.address] = 0
        cs = options.comm_safety
        if cs is not None and cs.timeout_address is not None:
            self.tables["holding"][cs.timeout_address] = max(
                1, round(cs.timeout_s / cs.timeout_unit_s))
        self.last_request = time.monotonic()
        self.tripped = False
        self.trips = 0
        self.requests = 0
        self.hang_s = 0.0
        self._watchdog: asyncio.Task[None] | None = None
        self.simdevice = SimDevice(id=options.device_id, simdata=self._simdata(),
                                   action=self._action)

    # -- the image ------------------------------------------------------------------------
    def _simdata(self) -> tuple[list[SimData], list[SimData], list[SimData], list[SimData]]:
        out = []
        for fn in ("coil", "discrete", "holding", "input"):
            addrs = sorted(self.tables[fn]) or [_PARKING]
            bits = fn in ("coil", "discrete")
            runs: list[SimData] = []
            start = prev = addrs[0]
            for a in addrs[1:] + [None]:
                if a is not None and a == prev + 1:
                    prev = a
                    continue
                n = prev - start + 1
                if bits:
                    runs.append(SimData(start, values=[False] * n, datatype=DataType.BITS))
                else:
                    runs.append(SimData(start, count=n, values=0, datatype=DataType.REGISTERS))
                if a is not None:
                    start = prev = a
            out.append(runs)
        return out[0], out[1], out[2], out[3]

    def output_value(self, name: str) -> float | None:
        """The present value (channel unit) of output `name` as the module holds it."""
        for p in self.outputs:
            if p.name == name:
                return self._value_of(p, p.address)
        raise KeyError(name)

    def safe_value(self, name: str) -> float | None:
        for p in self.outputs:
            if p.name == name and p.safe_address is not None:
                return self._value_of(p, p.safe_address)
        raise KeyError(name)

    def _value_of(self, p: ModbusPoint, address: int) -> float:
        t = self.tables[p.function]
        if p.is_bit:
            return float(t[address])
        return to_value(p, decode(p, [t[address + k] for k in range(p.words)]))

    def refresh_inputs(self) -> None:
        """Take a new sample when one is due (every request without a sample period),
        and keep the sample clock register current."""
        now = time.monotonic()
        if now - self._sampled_s >= self.sample_period_s:
            # on the period's grid, as a module's own timer would
            if self.sample_period_s > 0.0 and now - self._sampled_s < 2 * self.sample_period_s:
                self._sampled_s += self.sample_period_s
            else:
                self._sampled_s = now
            self.samples += 1
            self._take_sample()
        sc = self.options.sample_clock
        if sc is not None:
            t = self.tables[sc.function]
            if sc.holds == "counter":
                t[sc.address] = self.samples & 0xFFFF
            else:
                t[sc.address] = min(0xFFFF, round((now - self._sampled_s) / sc.unit_s))

    def _take_sample(self) -> None:
        for p in self.inputs:
            v = self.source(p.name)
            if v is None:
                continue
            t = self.tables[p.function]
            if p.is_bit:
                t[p.address] = 1 if v >= 0.5 else 0
            else:
                for k, w in enumerate(encode(p, to_raw(p, v))):
                    t[p.address + k] = w

    def watchdog_s(self) -> float | None:
        cs = self.options.comm_safety
        if cs is None:
            return None
        if cs.timeout_address is not None:
            return self.tables["holding"][cs.timeout_address] * cs.timeout_unit_s
        return cs.timeout_s

    def check_watchdog(self) -> None:
        """Outputs to their safe values once the host has been silent too long."""
        limit = self.watchdog_s()
        if limit is None or self.tripped or time.monotonic() - self.last_request <= limit:
            return
        self.tripped = True
        self.trips += 1
        for p in self.outputs:
            if p.safe_address is None:
                continue
            t = self.tables[p.function]
            for k in range(p.words):
                t[p.address + k] = t[p.safe_address + k]
            self.sink(p.name, self._value_of(p, p.address))

    def start_watchdog(self) -> None:
        """Run the watchdog on the running asyncio loop (once)."""
        if self._watchdog is None:
            self._watchdog = asyncio.get_running_loop().create_task(self._watch())

    def stop_watchdog(self) -> None:
        if self._watchdog is not None:
            self._watchdog.cancel()
            self._watchdog = None

    async def _watch(self) -> None:
        while True:
            self.check_watchdog()
            await asyncio.sleep(0.01)

    # -- pymodbus's hook ----------------------------------------------------------------------
    async def _action(self, fc: int, start: int, address: int, count: int,
                      registers: list[int], values: list[int] | list[bool] | None
                      ) -> ExcCodes | None:
        if self.hang_s > 0.0:
            await asyncio.sleep(self.hang_s)
            return ExcCodes.DEVICE_BUSY
        self.last_request = time.monotonic()
        self.tripped = False
        self.requests += 1
        if values is not None and fc in _FC_WRITE:
            self._apply_write(_FC_WRITE[fc], address, values)
            return None
        fn = _FC_READ.get(fc)
        if fn is None:
            return None
        if fn in ("holding", "input", "discrete"):  # discrete: a digital input module
            self.refresh_inputs()
        t = self.tables[fn]
        if fn in ("coil", "discrete"):  # registers hold 16 bits each, from bit 16*start
            first, last = address // 16, (address + count - 1) // 16
            for r in range(first, last + 1):
                bits = [bool(t.get(16 * r + b, 0)) for b in range(16)]
                registers[r - start] = SimUtils.bitsToRegisters(bits)[0]
        else:
            for a in range(address, address + count):
                registers[a - start] = t.get(a, 0)
        return None

    def _apply_write(self, fn: str, address: int,
                     values: list[int] | list[bool] | int) -> None:
        vals = values if isinstance(values, list) else [values]
        t = self.tables[fn]
        touched: dict[str, ModbusPoint] = {}
        for k, v in enumerate(vals):
            a = address + k
            if a in t:
                t[a] = (1 if v else 0) if fn == "coil" else int(v) & 0xFFFF
            p = self._out_at.get((fn, a))
            if p is not None:
                touched[p.name] = p
        for p in touched.values():
            self.sink(p.name, self._value_of(p, p.address))


class ModbusServer(Protocol):
    """What the emulated rig does with a started pymodbus server: shut it down."""

    async def shutdown(self) -> None: ...


async def serve_tcp(device: EmulatedModbusDevice, host: str, port: int) -> ModbusServer:
    """Start a Modbus TCP server for `device`; returns the server (await .shutdown())."""
    from pymodbus.server import ModbusTcpServer

    server = ModbusTcpServer(device.simdevice, address=(host, port))
    await server.serve_forever(background=True)
    device.start_watchdog()
    return server


async def serve_rtu(device: EmulatedModbusDevice, port: str, baud: int, parity: str = "N",
                    stopbits: int = 1, bytesize: int = 8) -> ModbusServer:
    """Start a Modbus RTU server on serial `port` (one end of a pty pair)."""
    from pymodbus.framer import FramerType
    from pymodbus.server import ModbusSerialServer

    server = ModbusSerialServer(device.simdevice, framer=FramerType.RTU, port=port,
                                baudrate=baud, parity=parity, stopbits=stopbits,
                                bytesize=bytesize, timeout=0.5, reconnect_delay=0.2)
    await server.serve_forever(background=True)
    device.start_watchdog()
    return server


async def serve_rtu_tcp(device: EmulatedModbusDevice, host: str, port: int
                        ) -> ModbusServer:
    """Start a server of Modbus RTU frames over TCP for `device` (an RS-485 device server
    in transparent mode: the driver's `rtu-tcp` transport, or its `rtu` transport on a
    pyserial `socket://host:port` URL): RTU framing and CRC without a pty between."""
    from pymodbus.framer import FramerType
    from pymodbus.server import ModbusTcpServer

    server = ModbusTcpServer(device.simdevice, framer=FramerType.RTU, address=(host, port))
    await server.serve_forever(background=True)
    device.start_watchdog()
    return server
