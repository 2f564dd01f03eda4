"""The `modbus` driver: analog and digital I/O modules over Modbus TCP or RTU (on a
serial port, or RTU frames over TCP through an RS-485 device server).

Channels come from a register map (`drivers/modbus_map.py`; built-in maps in
`drivers/modbus_presets.py`): inputs are read in as few requests as the map allows
once per poll cycle, each value stamped with the loop's clock when its response
arrived and a jitter, the request's round trip (the module sampled it in between),
or, for a module with a sample clock (`sample_clock`: a sample counter or
sample-age register), with the time the module took the sample (jitter: what the
clock leaves open, a counter's interval between reads, an age register's unit and
round trip); outputs are sent
when their register value changes and re-sent every `write_refresh_s`, never before
the loop has written them (start-up reads before it writes). Values are in the
channel's unit (volts); the rig's signal calibration goes on to SI.

All bus I/O runs on the driver's thread with pymodbus's synchronous client.
Exception responses, timeouts and disconnects are counted per cause and per
channel and logged with the device and channel named (`health()`).

A request left unanswered for `timeout_s` is re-sent at once, not taken for a lost
link. The physics: a real line (RS-485 noise, a CRC error, a device busy for a
moment) loses a reply now and then, and a reply lost that way is independent of the
next one (losing k in a row has probability p**k); a dead device, a cut cable or an
unplugged adapter misses every one. So only `lost_after` unanswered requests in a
row mean the link is lost: it is then closed and re-opened with backoff. One lost
reply costs one retry (`timeout_s` plus a round trip: `lost_reply_s()`, which the
config loader keeps within the timeout of every signal read through this driver);
a dead device is found as before: failure (from the first unanswered request) that
lasts `fault_after_s` sets `fault`, which the supervisor turns into the safe state.
An I/O error of the port or socket (not a missing reply) drops the link at once.

A module with a communication watchdog
gets the outputs' safe values (`set_safe_outputs`) written to its safe-value
registers, so it reaches the safe state by itself if this PC goes silent. The output
side (what to send when) is `drivers/modbus_writes.py`; the sample clock's times are
`modbus_map.SampleTimes`.
"""

from __future__ import annotations

import contextlib
import logging
import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Literal

from pamd.drivers import Channel, serial_port_claim
from pamd.drivers.device import Backoff, DeviceHealth, ThreadedDriver
from pamd.drivers.modbus_map import (
    MAX_WRITE_REGISTERS,
    Block,
    CommSafety,
    ModbusPoint,
    SampleClock,
    SampleTimes,
    check_points,
    decode,
    plan_blocks,
    to_value,
)
from pamd.drivers.modbus_presets import PRESETS
from pamd.drivers.modbus_writes import OutputWriter, Payload

from pamd.wire.errors import DriverError
from pamd.wire.schema.engine import spec

EXCEPTION_NAMES = {1: "illegal function", 2: "illegal data address", 3: "illegal data value",
                   4: "device failure", 5: "acknowledge", 6: "device busy",
                   10: "gateway path unavailable", 11: "gateway target did not respond"}


@dataclass(frozen=True, kw_only=True)
class ModbusOptions:
    """Options of the `modbus` driver."""

    transport: Literal["tcp", "rtu", "rtu-tcp"] = spec(
        "tcp", "Modbus TCP (Ethernet), RTU (RS-485 on a serial port) or rtu-tcp: RTU frames "
        "over a TCP connection (an RS-485 device server in transparent mode; the emulated "
        "rig's RTU line).")
    host: str = spec("127.0.0.1", "TCP and rtu-tcp: the module's (device server's) address.")
    port: int = spec(502, "TCP and rtu-tcp: the module's (device server's) port.", min=1,
                     max=65535)
    serial_port: str = spec("", "RTU: serial device or pyserial URL (/dev/ttyUSB0, "
                            "socket://host:port).")
    baud: int = spec(115200, "RTU and rtu-tcp: baud rate of the RS-485 line.", unit="baud",
                     min=300, max=4000000)
    parity: Literal["N", "E", "O"] = spec("N", "RTU: parity.")
    stopbits: int = spec(1, "RTU: stop bits.", min=1, max=2)
    bytesize: int = spec(8, "RTU: data bits.", min=7, max=8)
    device_id: int = spec(1, "Modbus device (unit/slave) id.", min=0, max=255)
    timeout_s: float = spec(0.1, "Wait this long for a response.", unit="s", gt=0.0)
    poll_period_s: float = spec(0.001, "Start a read cycle this often (0: back to back).",
                                unit="s", min=0.0, max=10.0)
    write_refresh_s: float = spec(0.5, "Re-send unchanged outputs this often.", unit="s",
                                  gt=0.0)
    reconnect_min_s: float = spec(0.05, "First reconnect delay (doubles per failure).",
                                  unit="s", gt=0.0)
    reconnect_max_s: float = spec(2.0, "Longest reconnect delay.", unit="s", gt=0.0)
    fault_after_s: float = spec(0.3, "Failure lasting this long sets the driver's fault.",
                                unit="s", gt=0.0)
    lost_after: int = spec(3, "Unanswered requests in a row that mean the link is lost (it "
                           "is re-opened); fewer are re-sent at once: a reply lost to noise "
                           "costs one retry.", min=1, max=20)
    max_gap: int = spec(0, "Read across up to this many unmapped registers to save requests "
                        "(only if the device answers for them).", min=0, max=100)
    preset: Literal["none", "adam-6024", "wago-750-559"] = spec(
        "none", "Built-in map, used when inputs and outputs are both empty.")
    inputs: tuple[ModbusPoint, ...] = spec((), "Input channels (read every poll cycle).")
    outputs: tuple[ModbusPoint, ...] = spec((), "Output channels (holding registers, coils).")
    comm_safety: CommSafety | None = spec(None, "The module's communication watchdog; null: "
                                          "none, or configured on the module.")
    sample_clock: SampleClock | None = spec(
        None, "The module's sample counter or sample-age register; null: none (values are "
        "stamped when read; state the rig signals' `sample_period_s` for a slow module).")


def effective_map(o: ModbusOptions) -> tuple[tuple[ModbusPoint, ...], tuple[ModbusPoint, ...]]:
    """The (inputs, outputs) in force: explicit ones, or the preset's."""
    if not o.inputs and not o.outputs and o.preset != "none":
        return PRESETS[o.preset]
    return o.inputs, o.outputs


class ModbusDriver(ThreadedDriver):
    """Modbus TCP/RTU analog and digital I/O."""

    options_type = ModbusOptions

    def __init__(self, name: str, options: ModbusOptions | None = None) -> None:
        o = options if options is not None else ModbusOptions()
        ins, outs = effective_map(o)
        problems = check_points(ins, False) + check_points(outs, True)
        if set(p.name for p in ins) & set(p.name for p in outs):
            problems.append("an input and an output share a name")
        sc = o.sample_clock
        if sc is not None and any(p.function == sc.function
                                  and p.address <= sc.address < p.address + p.words
                                  for p in ins):
            problems.append(f"sample_clock overlaps an input at {sc.function} address "
                            f"{sc.address}")
        if o.transport == "rtu" and not o.serial_port:
            problems.append("transport rtu needs serial_port")
        if problems:
            raise DriverError(f"modbus driver {name!r}: " + "; ".join(problems))
        self.in_points, self.out_points = ins, outs
        super().__init__(name, o)
        self.fault_after_s = o.fault_after_s
        # The sample clock register is read with the inputs: in the same request when its
        # address is near theirs (one atomic read), and always in the first request.
        self._clock_index = len(ins) if o.sample_clock is not None else -1
        read_points = ins if o.sample_clock is None else (*ins, ModbusPoint(
            name="sample_clock", function=o.sample_clock.function,
            address=o.sample_clock.address))
        self.read_blocks: list[Block] = sorted(
            plan_blocks(read_points, o.max_gap),
            key=lambda b: not any(i == self._clock_index for i, _ in b.members))
        self.write_blocks: list[Block] = plan_blocks(outs, 0, MAX_WRITE_REGISTERS)
        self.outputs = OutputWriter(outs, self.write_blocks, o.write_refresh_s)
        # Any: a pymodbus client (untyped third party; its calls are named in `request`)
        self._client: Any = None
        self.cycles = 0
        self._sample_times = (SampleTimes(o.sample_clock) if o.sample_clock is not None
                              else None)
        self._unanswered = 0  # requests unanswered in a row (lost_after: the link is lost)

    # -- Driver protocol ----------------------------------------------------------------
    def channels(self) -> Sequence[Channel]:
        ins, outs = effective_map(self.options)
        return ([Channel(p.name, "in", p.unit, p.is_bit) for p in ins]
                + [Channel(p.name, "out", p.unit, p.is_bit) for p in outs])

    def write(self, index: int, value: float) -> None:
        """Store the value; the thread sends it if its register value changed."""
        if not self.outputs.store(index, value):  # NaN never reaches a device
            self.count("dropped_writes")

    def set_safe_outputs(self, values: dict[int, float]) -> None:
        """Values (channel unit) for the module's comm-safety registers; outputs without
        a `safe_address` are counted as unsupported."""
        unsupported = self.outputs.set_safe(values)
        if unsupported:
            self.count("safe_unsupported", unsupported)

    def claims(self) -> tuple[str, ...]:
        """RTU: the serial port (one master on the line); rtu-tcp: the device server's
        address (its line has one master too); TCP: the device behind the address (a
        gateway may serve other device ids to other daemons)."""
        o: ModbusOptions = self.options
        if o.transport == "rtu":
            return serial_port_claim(o.serial_port)
        if o.transport == "rtu-tcp":
            return (f"Modbus RTU line at {o.host.lower()}:{o.port}",)
        return (f"Modbus TCP device {o.host.lower()}:{o.port} id {o.device_id}",)

    def describe(self) -> str:
        o: ModbusOptions = self.options
        where = (f"{o.transport} {o.host}:{o.port}" if o.transport != "rtu"
                 else f"rtu {o.serial_port} {o.baud} {o.bytesize}{o.parity}{o.stopbits}")
        return f"modbus {self.name!r} ({where}, id {o.device_id})"

    def lost_reply_s(self) -> float:
        """How much later than usual a fresh input can arrive when one reply is lost:
        the wait for it (`timeout_s`), the retry's round trip and the poll period (the
        loader keeps every signal's timeout above this plus its sample period). RTU
        (and rtu-tcp, whose device server has the line behind it): the round trip is
        the longest read's request and response frames on the line (11 bits a byte
        with start, stop and parity bits, at `baud`) plus the 3.5 characters of
        silence that end each frame; TCP: `timeout_s` dominates."""
        o: ModbusOptions = self.options
        rtt_s = 0.0
        if o.transport != "tcp" and self.read_blocks:
            words = max(b.count if b.function in ("holding", "input") else (b.count + 15) // 16
                        for b in self.read_blocks)
            rtt_s = (8 + 5 + 2 * words + 7) * 11.0 / o.baud
        return o.timeout_s + rtt_s + o.poll_period_s

    # -- the I/O thread ---------------------------------------------------------------
    def _connect(self) -> bool:
        o: ModbusOptions = self.options
        from pymodbus.client import ModbusSerialClient, ModbusTcpClient
        from pymodbus.framer import FramerType

        logging.getLogger("pymodbus.logging").setLevel(logging.CRITICAL)  # we count errors
        client: ModbusTcpClient | ModbusSerialClient
        if o.transport == "tcp":
            client = ModbusTcpClient(o.host, port=o.port, timeout=o.timeout_s, retries=0)
        elif o.transport == "rtu-tcp":
            client = ModbusTcpClient(o.host, port=o.port, framer=FramerType.RTU,
                                     timeout=o.timeout_s, retries=0)
        else:
            client = ModbusSerialClient(o.serial_port, framer=FramerType.RTU, baudrate=o.baud,
                                        bytesize=o.bytesize, parity=o.parity,
                                        stopbits=o.stopbits, timeout=o.timeout_s, retries=0)
        try:
            ok = bool(client.connect())
        except Exception:  # noqa: BLE001 - any failure to open is "not connected"
            ok = False
        if not ok:
            client.close()  # type: ignore[no-untyped-call]  # pymodbus: close() unannotated
            return False
        self._client = client
        self.connected = True
        self.count("connects")
        self.outputs.forget()  # the device may have restarted
        cs: CommSafety | None = self.options.comm_safety
        if cs is not None and cs.timeout_address is not None:
            ticks = max(1, round(cs.timeout_s / cs.timeout_unit_s))
            self.request("write_registers", cs.timeout_address, [ticks], (),
                          "comm-safety watchdog time")
        return self._client is not None

    def _drop(self) -> None:
        if self._client is not None:
            with contextlib.suppress(Exception):
                self._client.close()
        self._client = None
        self.connected = False

    def release(self) -> None:
        self._drop()

    def run(self) -> None:
        o: ModbusOptions = self.options
        backoff = Backoff(o.reconnect_min_s, o.reconnect_max_s)
        mono = time.monotonic
        while not self.stopping.is_set():
            if self._client is None:
                if not self._connect():
                    self.count("connect_failures")
                    tries = self.counters.get("connect_failures", 0)
                    self.failing(f"cannot connect ({tries} attempts so far, retrying)")
                    self.stopping.wait(backoff.next())
                    continue
                backoff.reset()
            t0 = mono()
            problem = self._cycle()
            if problem is None:
                self.healthy()
            else:
                self.failing(problem)
            self.cycles += 1
            if o.poll_period_s > 0.0:
                rest = t0 + o.poll_period_s - mono()
                if rest > 0.0:
                    self.stopping.wait(rest)
        self._drop()

    def _cycle(self) -> str | None:
        """Writes, then reads. Returns the first problem, or None."""
        problem = self.outputs.write_outputs(self)
        if self._client is None:
            return problem
        p2 = self.outputs.write_safe_values(self)
        problem = problem or p2
        clock = self.clock
        for blk in self.read_blocks:
            if self._client is None:
                return problem or "link lost"
            fn = {"holding": "read_holding_registers", "input": "read_input_registers",
                  "coil": "read_coils", "discrete": "read_discrete_inputs"}[blk.function]
            sent = clock()
            rr = self.request(fn, blk.start, blk.count, blk.names, blk.label)
            if isinstance(rr, str):
                problem = problem or rr
                continue
            now = clock()
            jitter = now - sent
            data = rr.bits if blk.function in ("coil", "discrete") else rr.registers
            if len(data) < blk.count:
                problem = problem or self.error(
                    "short_responses", f"{blk.label}: {len(data)} values for {blk.count}",
                    blk.names)
                if self._clock_index >= 0:
                    return problem  # without the sample's time no value can be stamped
                continue
            times = self._sample_times
            if times is not None:
                for i, off in blk.members:
                    if i == self._clock_index:
                        times.read(data[off] & 0xFFFF, now, jitter)
                now, jitter = times.sample_s, times.jitter_s
            for i, off in blk.members:
                if i == self._clock_index:
                    continue
                pt = self.in_points[i]
                if pt.is_bit:
                    raw = 1.0 if data[off] else 0.0
                else:
                    raw = decode(pt, data[off:off + pt.words])
                self.stamp(i, to_value(pt, raw), now, jitter)
            self.count("reads")
        return problem

    def request(self, fn: str, address: int, arg: Payload, names: tuple[str, ...],
                label: str) -> Any:  # Any: a pymodbus response (untyped), or a message
        """One transaction; returns the response, or a message (str) naming the device,
        the request and its channels. An unanswered request is re-sent at once until
        `lost_after` in a row went unanswered; then, or on an I/O error, the link is
        dropped for a reconnect (module docstring: the physics)."""
        client = self._client
        if client is None:
            return f"{label}: not connected"
        o: ModbusOptions = self.options
        dev = o.device_id
        while True:
            try:
                if fn.startswith("read"):
                    rr = getattr(client, fn)(address, count=arg, device_id=dev)
                else:
                    rr = getattr(client, fn)(address, arg, device_id=dev)
            except Exception as exc:  # noqa: BLE001 - timeouts, resets, garbage: all counted
                text = f"{label}: {type(exc).__name__}: {exc}"
                if "No response" not in str(exc) and "timed out" not in str(exc):
                    self._drop()
                    self.count("disconnects")
                    return self.error("link_errors", text, names)
                self._unanswered += 1
                self.error("timeouts", text, names)
                self.failing(text)  # failure starts with the first unanswered request
                if self._unanswered < o.lost_after:
                    self.count("retries")
                    continue
                self._drop()
                self.count("disconnects")
                return (f"{self.describe()}: {label}: no response to {self._unanswered} "
                        f"requests in a row (lost_after {o.lost_after}): link lost")
            self._unanswered = 0
            break
        if rr.isError():
            code = getattr(rr, "exception_code", 0)
            what = EXCEPTION_NAMES.get(code, f"code {code}")
            return self.error(f"exception.{code}", f"{label}: exception response {code} "
                              f"({what})", names)
        return rr

    def health(self) -> DeviceHealth:
        h = super().health()
        h.counters["cycles"] = self.cycles
        return h
