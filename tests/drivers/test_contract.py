"""The driver contract, one suite run against every driver of the `pamd.drivers` entry
points (as python-can runs one suite over its interfaces): sim, modbus (over loopback
TCP, over RTU on socat ptys and RTU frames over TCP, against the emulated module),
serial-line (a pty), canopen-encoder (python-can's virtual bus, and its socketcand
client against the emulator's socketcand server, with an emulated CiA 406 node) and
nidaqmx (NI's own client library against the emulator's NI gRPC Device Server, on the
card's sample clock).

What `pamd.drivers.Driver` promises: found by its entry point, options a documented
frozen dataclass and bad ones refused with a DriverError naming the driver; channels
known before `open`, inputs NaN and never stamped until read; `open` never waits for
the device; readings flow with advancing stamps and a healthy `health()`; writes never
raise on an existing output (nor on NaN) and are refused for a missing one;
`set_safe_outputs`, `preset_input`, `is_absolute` never raise; a device that goes
silent or was never there faults with a sentence naming the driver and its stamps
stop; it recovers by itself; `close` ends its I/O thread.

Driver-specific behaviour (scaling, maps, checksums, SDO, comm-safety registers...)
stays in each driver's own tests."""

from __future__ import annotations

import dataclasses
import math
import os
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest
from pamd.drivers import Driver, DriverHealth, available_drivers, load_driver_class
from pamd.drivers.can_frames import EncoderNode
from pamd.drivers.canopen_encoder import CanEncoderOptions
from pamd.drivers.modbus import ModbusOptions
from pamd.drivers.modbus_map import ModbusPoint
from pamd.drivers.nidaq_options import (
    AnalogInput,
    AnalogOutput,
    DigitalLine,
    EncoderInput,
    NidaqOptions,
)
from pamd.drivers.serial_line import LineField, SerialLineOptions
from pamd.drivers.sim import SimDriver

from pamd.config import load_config
from pamd.emulate.modbus_device import (
    EmulatedModbusDevice,
    serve_rtu,
    serve_rtu_tcp,
    serve_tcp,
)
from pamd.emulate.nidaq_device import USB_6211, EmulatedDaq
from pamd.emulate.nidaq_server import DaqServer
from pamd.emulate.ptys import PtyPair
from pamd.emulate.socketcand import SocketcandServer
from pamd.emulate.testing import AioThread, emulated_dict, free_port, wait_until, write_config
from pamd.sim.options import SimMuscleOptions, SimOptions
from pamd.wire.errors import DriverError

WAIT_S = 20.0  # generous: this machine is busy; a pass takes a fraction of it


class Bench:
    """One driver type on a device it can talk to (or a simulated rig)."""

    type_name: str
    fault_words: tuple[str, ...] = ()  # besides the driver's name, in its fault text
    virtual = False  # the loop advances it (`steps_with_loop`)

    def __init__(self, tmp: Path) -> None:
        self.tmp = tmp
        self.made: list[Driver] = []
        self.t_s = 0.0

    def clock(self) -> float:
        return self.t_s if self.virtual else time.monotonic()

    def options(self) -> Any:
        """Options for a driver of the device this bench serves."""
        raise NotImplementedError

    def bad_options(self) -> tuple[Any, str]:
        """Options the driver refuses at construction, and a word of the refusal."""
        raise NotImplementedError

    def absent_options(self) -> Any | None:
        """Options naming a device that is not there (None: cannot be absent)."""
        return None

    def silence(self) -> None:
        """The device stops answering."""
        raise NotImplementedError

    def restore(self) -> None:
        """The device answers again."""
        raise NotImplementedError

    def close(self) -> None:
        pass

    # -- what this driver adds to the contract's checks -----------------------------------
    def check_fault(self, d: Driver, fault: str) -> None:
        """More of a silent device's fault text and counters."""

    def check_recovered(self, d: Driver) -> None:
        """More of a recovery."""

    def check_absent(self, d: Driver) -> None:
        """More of an absent device's fault, once it has been retried."""

    # -- helpers ------------------------------------------------------------------------
    def make(self, options: Any = None) -> Driver:
        cls = load_driver_class(self.type_name)
        d = cls("dut", self.options() if options is None else options)
        self.made.append(d)
        return d

    def wait(self, pred: Callable[[], Any], timeout_s: float = WAIT_S) -> bool:
        """Until `pred` holds; a simulated rig is advanced by the loop's period."""
        if not self.virtual:
            return wait_until(pred, timeout_s)
        for _ in range(int(timeout_s / 0.001)):
            if pred():
                return True
            self.advance(0.001)
        return bool(pred())

    def advance(self, dt_s: float) -> None:
        self.t_s += dt_s
        for d in self.made:
            d.advance(dt_s)

    def pause(self, s: float) -> None:
        """Let `s` of the driver's time pass."""
        if self.virtual:
            for _ in range(round(s / 0.001)):
                self.advance(0.001)
        else:
            time.sleep(s)


class SimBench(Bench):
    type_name = "sim"
    virtual = True
    fault_words = ("stopped answering",)

    def options(self) -> SimOptions:
        return SimOptions()

    def bad_options(self) -> tuple[Any, str]:
        twice = (SimMuscleOptions(name="a"), SimMuscleOptions(name="a"))
        return SimOptions(muscles=twice), "used twice"

    def silence(self) -> None:
        for d in self.made:
            assert isinstance(d, SimDriver)
            d.inject_fault("*", "driver", "error")

    def restore(self) -> None:
        for d in self.made:
            assert isinstance(d, SimDriver)
            d.clear_faults()


class ModbusTcpBench(Bench):
    """The ADAM-6024 of config/rig-emulated.yaml, emulated on a free loopback port."""

    type_name = "modbus"
    fault_words = ("tcp 127.0.0.1",)

    def __init__(self, tmp: Path) -> None:
        super().__init__(tmp)
        port = free_port()
        cfg = load_config(str(write_config(tmp, emulated_dict(tmp, port, can="virtual"))))
        io = next(d.options for d in cfg.rig.drivers if d.name == "io")
        self.opts = dataclasses.replace(io, fault_after_s=0.2, reconnect_max_s=0.2,
                                        timeout_s=0.1)
        self.aio = AioThread()
        self.shown: dict[str, float] = {"ai0": 1.0, "ai1": 2.0, "ai2": 1.5, "ai3": 0.5}
        self.device = EmulatedModbusDevice(self.opts, self.shown.get, lambda k, v: None)
        self.server: Any = None
        self.restore()

    def options(self) -> ModbusOptions:
        return self.opts

    def bad_options(self) -> tuple[Any, str]:
        return dataclasses.replace(self.opts, transport="rtu", serial_port=""), "serial_port"

    def absent_options(self) -> ModbusOptions:
        return dataclasses.replace(self.opts, port=free_port())

    def silence(self) -> None:
        self.aio.run(self.server.shutdown())
        self.server = None

    def check_recovered(self, d: Driver) -> None:
        assert d.connected  # type: ignore[attr-defined]
        assert d.health().counters["connects"] >= 2  # it reconnected

    def restore(self) -> None:
        self.server = self.aio.run(serve_tcp(self.device, "127.0.0.1", self.opts.port))

    def close(self) -> None:
        if self.server is not None:
            self.silence()
        self.aio.stop()


class ModbusRtuBench(Bench):
    """A float32 load-cell transmitter at 115200 baud on a socat pty pair."""

    type_name = "modbus"
    fault_words = ("rtu",)

    def __init__(self, tmp: Path) -> None:
        super().__init__(tmp)
        self.host = str(tmp / "rtu")
        self.opts = ModbusOptions(
            transport="rtu", serial_port=self.host, baud=115200, device_id=7, timeout_s=0.05,
            poll_period_s=0.0, fault_after_s=0.2, reconnect_max_s=0.2,
            inputs=(ModbusPoint(name="force", function="input", address=0, type="float32",
                                unit="N"),),
            outputs=(ModbusPoint(name="tare", function="coil", address=0, unit=""),))
        self.aio = AioThread()
        self.device = EmulatedModbusDevice(self.opts, {"force": 294.3}.get, lambda k, v: None)
        self.pair: PtyPair | None = None
        self.server: Any = None
        self.restore()

    def options(self) -> ModbusOptions:
        return self.opts

    def bad_options(self) -> tuple[Any, str]:
        return dataclasses.replace(self.opts, serial_port=""), "serial_port"

    def absent_options(self) -> ModbusOptions:
        return dataclasses.replace(self.opts, serial_port=str(self.tmp / "unplugged"))

    def check_fault(self, d: Driver, fault: str) -> None:
        assert str(self.tmp) in fault  # the port, by its path

    def silence(self) -> None:  # the USB adapter is unplugged
        assert self.pair is not None
        self.aio.run(self.server.shutdown())
        self.pair.close()
        self.pair = self.server = None

    def restore(self) -> None:
        self.pair = PtyPair(self.host)
        self.server = self.aio.run(serve_rtu(self.device, self.pair.device, 115200))

    def close(self) -> None:
        if self.pair is not None:
            self.silence()
        self.aio.stop()


class SerialLineBench(Bench):
    """A load-cell amplifier streaming NMEA-checked lines on a pty."""

    type_name = "serial-line"
    fault_words = ("silent",)

    def __init__(self, tmp: Path) -> None:
        super().__init__(tmp)
        self.master, self.slave = os.openpty()
        self.path = os.ttyname(self.slave)
        self.talking = threading.Event()
        self.stopping = threading.Event()
        self.thread = threading.Thread(target=self._stream, daemon=True)
        self.talking.set()
        self.thread.start()

    def _stream(self) -> None:
        k = 0
        while not self.stopping.wait(0.005):
            if self.talking.is_set():
                body = f"F,{100.0 + k % 7:.1f},{k}"
                x = 0
                for b in body.encode():
                    x ^= b
                os.write(self.master, f"${body}*{x:02X}\r\n".encode())
                k += 1

    def options(self) -> SerialLineOptions:
        return SerialLineOptions(
            port=self.path, baud=115200, delimiter=",", checksum="nmea", timeout_s=0.1,
            fault_after_s=0.1, reconnect_max_s=0.05,
            channels=(LineField(name="force", field=1, unit="N"),
                      LineField(name="count", field=2)))

    def bad_options(self) -> tuple[Any, str]:
        return SerialLineOptions(mode="poll", channels=(LineField(name="f"),)), "request"

    def absent_options(self) -> SerialLineOptions:
        return dataclasses.replace(self.options(), port=str(self.tmp / "nothing"))

    def silence(self) -> None:
        self.talking.clear()

    def check_absent(self, d: Driver) -> None:
        assert "cannot open" in d.fault  # type: ignore[operator]
        assert wait_until(lambda: d.health().counters.get("open_failures", 0) >= 3)

    def restore(self) -> None:
        self.talking.set()

    def close(self) -> None:
        self.stopping.set()
        self.thread.join(5.0)
        os.close(self.master)
        os.close(self.slave)


class CanEncoderBench(Bench):
    """A CiA 406 encoder (canopen's LocalNode) on a private virtual CAN channel."""

    type_name = "canopen-encoder"
    fault_words = ("node 5 (pos)", "silent")

    def __init__(self, tmp: Path) -> None:
        import canopen

        from pamd.emulate.canopen_node import EmulatedEncoder

        super().__init__(tmp)
        self.channel = f"pamd-contract-{time.monotonic_ns()}"
        self.net = canopen.Network()
        self.net.NOTIFIER_CYCLE = 0.05  # its close waits for one idle wake-up, not 1 s
        self.net.connect(interface="virtual", channel=self.channel)
        self.encoder = EmulatedEncoder(self.net, 5)
        self.encoder.physical = 12345
        self.encoder.start()

    def options(self) -> CanEncoderOptions:
        return CanEncoderOptions(interface="virtual", channel=self.channel, fault_after_s=0.1,
                                 encoders=(EncoderNode(name="pos", node_id=5,
                                                       heartbeat_ms=20),))

    def bad_options(self) -> tuple[Any, str]:
        return CanEncoderOptions(interface="virtual", channel=self.channel), "at least one"

    def absent_options(self) -> CanEncoderOptions:
        return CanEncoderOptions(interface="virtual", channel=self.channel, fault_after_s=0.1,
                                 sdo_timeout_s=0.05,
                                 encoders=(EncoderNode(name="ghost", node_id=9),))

    def silence(self) -> None:
        self.encoder.go_silent()

    def check_absent(self, d: Driver) -> None:
        assert "node 9 (ghost)" in d.fault  # type: ignore[operator]
        assert d.health().counters["sdo_timeouts"] >= 1

    def restore(self) -> None:
        self.encoder.go_silent(False)

    def close(self) -> None:
        self.encoder.stop()
        self.net.disconnect()


class ModbusRtuTcpBench(ModbusTcpBench):
    """The load-cell transmitter of config/rig-emulated.yaml: RTU frames over TCP (an
    RS-485 device server), pymodbus's TCP client with its RTU framer against the
    emulator's server; the device server switched off and on again (the options, the
    switching and the closing as the TCP bench's)."""

    fault_words = ("rtu-tcp 127.0.0.1",)

    def __init__(self, tmp: Path) -> None:
        Bench.__init__(self, tmp)
        cfg = load_config(str(write_config(tmp, emulated_dict(tmp, free_port(),
                                                              can="virtual"))))
        lc2 = next(d.options for d in cfg.rig.drivers if d.name == "lc2")
        assert lc2.transport == "rtu-tcp"  # the shipped link
        self.opts = dataclasses.replace(lc2, fault_after_s=0.2, reconnect_max_s=0.2)
        self.aio = AioThread()
        self.device = EmulatedModbusDevice(self.opts, {"force": 294.3}.get, lambda k, v: None)
        self.server: Any = None
        self.restore()

    def check_recovered(self, d: Driver) -> None:
        assert d.health().counters["connects"] >= 2  # it reconnected

    def restore(self) -> None:
        self.server = self.aio.run(serve_rtu_tcp(self.device, "127.0.0.1", self.opts.port))


class CanSocketcandBench(Bench):
    """A CiA 406 encoder behind the emulator's socketcand server, read through
    python-can's own `socketcand` client; the server switched off and on again (the
    link lost: the bus re-opened, the node configured again)."""

    type_name = "canopen-encoder"
    fault_words = ("socketcand can0 at 127.0.0.1",)

    def __init__(self, tmp: Path) -> None:
        import canopen

        from pamd.emulate.canopen_node import EmulatedEncoder

        super().__init__(tmp)
        self.channel = f"pamd-contract-cand-{time.monotonic_ns()}"
        self.port = free_port()
        self.net = canopen.Network()
        self.net.NOTIFIER_CYCLE = 0.05
        self.net.connect(interface="virtual", channel=self.channel)
        self.encoder = EmulatedEncoder(self.net, 5)
        self.encoder.physical = 12345
        self.encoder.start()
        self.server: SocketcandServer | None = None
        self.restore()

    def options(self) -> CanEncoderOptions:
        return CanEncoderOptions(interface="socketcand", host="127.0.0.1", port=self.port,
                                 channel="can0", fault_after_s=0.1,
                                 encoders=(EncoderNode(name="pos", node_id=5,
                                                       heartbeat_ms=20),))

    def bad_options(self) -> tuple[Any, str]:
        return CanEncoderOptions(interface="socketcand", channel="can0",
                                 encoders=(EncoderNode(name="pos", node_id=5),)), "host"

    def absent_options(self) -> CanEncoderOptions:
        return dataclasses.replace(self.options(), port=free_port())

    def silence(self) -> None:
        assert self.server is not None
        self.server.stop()
        self.server = None

    def check_recovered(self, d: Driver) -> None:
        c = d.health().counters
        assert c["bus_opens"] >= 2 and c["nodes_started"] >= 2 and c["bus_errors"] >= 1

    def check_absent(self, d: Driver) -> None:
        assert "cannot open" in d.fault  # type: ignore[operator]
        assert wait_until(lambda: d.health().counters.get("bus_open_failures", 0) >= 2)

    def restore(self) -> None:
        self.server = SocketcandServer("127.0.0.1", self.port, "can0", self.channel)
        self.server.start()

    def close(self) -> None:
        if self.server is not None:
            self.silence()
        self.encoder.stop()
        self.net.disconnect()


class NidaqBench(Bench):
    """A USB-6211's channels (config/rig-nidaq-emulated.yaml's, and an encoder) behind
    the emulator's NI gRPC Device Server, hardware-timed at 200 Hz on the card's sample
    clock; the device pulled (DAQmx -201003) and plugged back."""

    type_name = "nidaqmx"
    fault_words = ("Dev1", "-201003")

    def __init__(self, tmp: Path) -> None:
        super().__init__(tmp)
        shown = {"dev1/ai0": 3.0, "dev1/ai1": 1.5, "dev1/ctr0": 200.0, "dev1/port0/line0": 1.0}
        self.device = EmulatedDaq("Dev1", USB_6211, shown.get, lambda k, v: None)
        self.server = DaqServer({"Dev1": self.device}, "127.0.0.1", free_port())
        self.server.start()

    def options(self) -> NidaqOptions:
        return NidaqOptions(
            server=self.server.address, timing="hardware_timed", sample_rate_hz=200.0,
            fault_after_s=0.2, reconnect_max_s=0.2,
            analog_inputs=(AnalogInput(name="pressure", physical_channel="Dev1/ai0"),
                           AnalogInput(name="force", physical_channel="Dev1/ai1")),
            encoders=(EncoderInput(name="length", counter="Dev1/ctr0", mm_per_pulse=0.04),),
            analog_outputs=(AnalogOutput(name="valve", physical_channel="Dev1/ao0"),),
            digital_inputs=(DigitalLine(name="estop", line="Dev1/port0/line0"),),
            digital_outputs=(DigitalLine(name="dump", line="Dev1/port1/line0"),))

    def bad_options(self) -> tuple[Any, str]:
        return dataclasses.replace(self.options(), analog_inputs=(
            AnalogInput(name="p", physical_channel="Dev1:ai0"),)), "physical name"

    def absent_options(self) -> NidaqOptions:
        return dataclasses.replace(self.options(), server=f"127.0.0.1:{free_port()}")

    def silence(self) -> None:
        self.device.remove()

    def restore(self) -> None:
        self.device.reinsert()

    def check_recovered(self, d: Driver) -> None:
        assert d.health().counters["connects"] >= 2  # its tasks made again

    def check_absent(self, d: Driver) -> None:
        assert "does not answer" in d.fault  # type: ignore[operator]
        assert wait_until(lambda: d.health().counters.get("connect_failures", 0) >= 2)

    def close(self) -> None:
        self.server.stop()


BENCHES: dict[str, type[Bench]] = {
    "sim": SimBench, "modbus-tcp": ModbusTcpBench, "modbus-rtu": ModbusRtuBench,
    "modbus-rtu-tcp": ModbusRtuTcpBench, "serial-line": SerialLineBench,
    "canopen-encoder": CanEncoderBench, "canopen-socketcand": CanSocketcandBench,
    "nidaqmx": NidaqBench,
}


@pytest.fixture(params=list(BENCHES))
def bench(request: pytest.FixtureRequest, tmp_path: Path) -> Iterator[Bench]:
    if request.param == "modbus-rtu":
        request.getfixturevalue("socat")  # missing: fails saying so
    b = BENCHES[request.param](tmp_path)
    try:
        yield b
    finally:
        for d in b.made:
            d.close()
        b.close()


def test_every_installed_driver_is_under_contract() -> None:
    assert set(available_drivers()) == {b.type_name for b in BENCHES.values()}


def test_found_by_its_entry_point_with_documented_options(bench: Bench) -> None:
    cls = load_driver_class(bench.type_name)
    assert issubclass(cls, Driver)
    opts = cls.options_type
    assert dataclasses.is_dataclass(opts) and opts.__dataclass_params__.frozen  # type: ignore[attr-defined]
    for f in dataclasses.fields(opts):
        assert f.metadata.get("doc"), f"{bench.type_name} option {f.name} has no doc"
    assert isinstance(bench.options(), opts)
    bad, word = bench.bad_options()
    with pytest.raises(DriverError) as exc:
        cls("dut", bad)
    assert "'dut'" in str(exc.value) and word in str(exc.value)


def test_channels_are_known_before_open_and_nothing_is_read_yet(bench: Bench) -> None:
    d = bench.make()
    ins, outs = d.input_channels, d.output_channels
    assert ins and [c.direction for c in ins] == ["in"] * len(ins)
    assert [c.direction for c in outs] == ["out"] * len(outs)
    names = [c.name for c in (*ins, *outs)]
    assert len(set(names)) == len(names)
    assert all(math.isnan(v) for v in d.in_values) and len(d.in_values) == len(ins)
    assert d.in_stamps_s == [-math.inf] * len(ins) and d.preset_counts == [0] * len(ins)
    for i, c in enumerate(ins):
        assert d.input_index(c.name) == i and isinstance(d.is_absolute(i), bool)
    for i, c in enumerate(outs):
        assert d.output_index(c.name) == i
    with pytest.raises(KeyError):
        d.input_index("no-such-channel")
    with pytest.raises(KeyError):
        d.output_index("no-such-channel")


def test_readings_flow_with_advancing_stamps_and_a_healthy_report(bench: Bench) -> None:
    d = bench.make()
    d.open(bench.clock)
    assert bench.wait(lambda: all(math.isfinite(v) for v in d.in_values)
                      and d.health().ok)
    stamps = list(d.in_stamps_s)
    assert all(math.isfinite(s) and s <= bench.clock() for s in stamps)
    assert bench.wait(lambda: all(s > s0 for s, s0 in zip(d.in_stamps_s, stamps,
                                                           strict=True)))
    h = d.health()
    assert isinstance(h, DriverHealth) and h.ok and h.fault is None and d.fault is None
    assert all(isinstance(v, int) for v in h.counters.values())


def test_writes_never_raise_on_an_output_and_are_refused_beyond_them(bench: Bench) -> None:
    d = bench.make()
    d.open(bench.clock)
    for i in range(len(d.output_channels)):
        d.write(i, 1.0)
        d.write(i, math.nan)  # dropped, never sent
    with pytest.raises((IndexError, DriverError)):
        d.write(len(d.output_channels), 1.0)
    d.set_safe_outputs({i: 0.0 for i in range(len(d.output_channels))})
    d.set_safe_outputs({})
    for i in range(len(d.input_channels)):
        assert isinstance(d.is_absolute(i), bool)
    assert bench.wait(lambda: d.health().ok)


def test_a_silent_device_faults_naming_the_driver_its_stamps_stop_and_it_recovers(
        bench: Bench) -> None:
    d = bench.make()
    d.open(bench.clock)
    assert bench.wait(lambda: d.health().ok and all(math.isfinite(s) for s in d.in_stamps_s))
    bench.silence()
    assert bench.wait(lambda: d.fault is not None)
    fault = d.fault
    assert isinstance(fault, str) and "'dut'" in fault, fault
    for word in bench.fault_words:
        assert word in fault, fault
    bench.check_fault(d, fault)
    h = d.health()
    assert not h.ok and h.fault == fault
    stamps = list(d.in_stamps_s)
    bench.pause(0.3)
    assert d.in_stamps_s == stamps  # stale: nothing new while it is silent
    bench.restore()
    assert bench.wait(lambda: d.fault is None and all(
        s > s0 for s, s0 in zip(d.in_stamps_s, stamps, strict=True)))
    assert bench.wait(lambda: d.health().ok)
    bench.check_recovered(d)


def test_open_never_waits_for_an_absent_device_which_faults_and_is_retried(
        bench: Bench) -> None:
    opts = bench.absent_options()
    if opts is None:
        assert bench.virtual  # only a simulated rig is always there
        return
    d = bench.make(opts)
    d.open(bench.clock)  # returns at once: the device is looked for on its own thread
    assert bench.wait(lambda: d.fault is not None)
    assert "'dut'" in d.fault  # type: ignore[operator]
    assert not d.health().ok and all(s == -math.inf for s in d.in_stamps_s)
    bench.check_absent(d)


def test_close_ends_the_io_thread(bench: Bench) -> None:
    before = set(threading.enumerate())
    d = bench.make()
    d.open(bench.clock)
    assert bench.wait(lambda: d.health().ok)
    d.close()
    assert wait_until(lambda: not [t for t in set(threading.enumerate()) - before
                                   if t.is_alive() and "dut" in t.name])
