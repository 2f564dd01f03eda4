"""The emulated rig: a rig config's field devices served through their real
protocols, with the simulated muscles behind them.

For every driver in the config the emulator plays the device that driver expects:
- `modbus` over TCP: a Modbus TCP server on the configured (loopback) host/port;
- `modbus` over rtu-tcp, or RTU on a pyserial `socket://host:port` URL: a server of
  Modbus RTU frames over TCP on that (loopback) address;
- `modbus` over RTU on a device path: a Modbus RTU server on the far end of a socat
  pty pair whose near end is the driver's `serial_port`;
- `canopen-encoder`: one emulated CiA 406 node per encoder on a canopen network:
  `socketcand` (a socketcand server on the driver's loopback host/port,
  `socketcand.py`), python-can's `serial` interface over a pty pair, or `virtual` (in
  one process, for tests).
Links between processes go over loopback sockets by default (config/rig-emulated.yaml):
a pty's data passes the kernel's tty layer, which beside CPU hogs delivered up to 91 ms
late (bench/pty_delivery.py) and made the daemon's readings stale; ptys stay an option
(a real USB-RS485 adapter is a tty).
The devices' channels are wired to the simulated muscles through the config's own
signal bindings (`physics.EmulatedPlant`), so the daemon running the same config
sees a consistent rig. `sim` drivers are skipped; `serial-line` devices and raw CAN
frames are not emulated (a notice says so).
"""

from __future__ import annotations

import asyncio
import contextlib
import os
import select
import threading
import time
from collections.abc import Coroutine
from typing import TYPE_CHECKING, TypeVar

from pamd.config.loader import LoadedConfig
from pamd.drivers.can_frames import EncoderNode
from pamd.drivers.canopen_encoder import CanEncoderOptions
from pamd.drivers.modbus import ModbusOptions
from pamd.drivers.nidaq import NidaqDriver
from pamd.emulate.lateness import Lateness
from pamd.emulate.modbus_device import (
    EmulatedModbusDevice,
    ModbusServer,
    serve_rtu,
    serve_rtu_tcp,
    serve_tcp,
)
from pamd.emulate.nidaq_device import PRODUCTS, USB_6211, EmulatedDaq
from pamd.emulate.physics import EmulatedPlant
from pamd.emulate.ptys import PtyPair
from pamd.emulate.socketcand import SocketcandServer

if TYPE_CHECKING:  # canopen, nidaqmx's stubs (and what is built on them) when a rig has one
    import canopen

    from pamd.drivers.nidaq_options import NidaqOptions
    from pamd.emulate.canopen_node import EmulatedEncoder
    from pamd.emulate.nidaq_server import DaqServer

LOOPBACK = ("127.0.0.1", "localhost", "::1")
_T = TypeVar("_T")


async def _cancel_all() -> None:
    me = asyncio.current_task()
    for task in asyncio.all_tasks():
        if task is not me:
            task.cancel()


#: how often the Modbus servers' event loop is checked for lag
LAG_CHECK_S = 0.01


def realtime_priority(priority: int) -> str | None:
    """Put the calling thread on SCHED_FIFO `priority` before the devices start: their
    threads and the socat links inherit it. The emulator stands in for I/O modules and
    encoders, which have CPUs of their own; at normal priority on a busy PC it is
    starved and its devices answer late, a fault no real rig would have. Returns why it
    could not (the emulator runs on at normal priority), or None."""
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))
    except (OSError, AttributeError) as exc:
        return (f"could not run the emulated devices at SCHED_FIFO {priority} ({exc}); they "
                "run at normal priority and a busy PC can make them answer late (needs "
                "CAP_SYS_NICE or an RLIMIT_RTPRIO of at least the priority)")
    return None


async def _watch_lag(lateness: Lateness) -> None:
    """Note how late the event loop (the Modbus servers) wakes from a short sleep."""
    loop = asyncio.get_running_loop()
    while True:
        due = loop.time() + LAG_CHECK_S
        await asyncio.sleep(LAG_CHECK_S)
        lateness.note(loop.time() - due)


#: longest a heartbeat task may take to see its stop (its period: 0x1017, 100 ms here)
CYCLIC_JOIN_S = 2.0


def _join_cyclic_senders(hosts: list[str], timeout_s: float) -> None:
    """Wait for python-can's periodic-send threads (the nodes' heartbeats) to end.
    `stop()` only flags them: a thread asleep until its next frame wakes and sends once
    more, and one whose daemon has gone is blocked writing into a full pty (nobody reads
    the host end); either, on the closed bus, was a traceback on the emulator's stderr
    when an operator's `pamd emulate` ended. So the host ends are read (and what they
    hold thrown away) until every such thread has seen its stop."""
    senders = [t for t in threading.enumerate()
               if t.name.startswith("Cyclic send task") and t is not threading.current_thread()]
    fds = []
    for host in hosts:
        with contextlib.suppress(OSError):
            fds.append(os.open(host, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK))
    deadline = time.monotonic() + timeout_s
    try:
        while any(t.is_alive() for t in senders) and time.monotonic() < deadline:
            ready = select.select(fds, [], [], 0.01)[0] if fds else []
            for fd in ready:
                with contextlib.suppress(OSError):
                    os.read(fd, 65536)
            if not fds:
                time.sleep(0.01)
    finally:
        for fd in fds:
            os.close(fd)


def loopback(driver: str, host: str) -> str:
    """`host` if it is a loopback address; the emulator serves nothing else."""
    if host not in LOOPBACK:
        raise RuntimeError(f"driver {driver!r}: the emulator serves on loopback only, "
                           f"not {host}")
    return host


def socket_url(port: str) -> tuple[str, int] | None:
    """(host, port) of a pyserial `socket://host:port` URL, else None."""
    if not port.startswith("socket://"):
        return None
    host, _, number = port[len("socket://"):].partition("?")[0].rpartition(":")
    if not host or not number.isdigit():
        raise RuntimeError(f"serial port {port!r}: a socket URL is socket://host:port")
    return host, int(number)


class EmulatedRig:
    """Start with `start()`, stop with `stop()`; `endpoints` says what serves where."""

    def __init__(self, cfg: LoadedConfig, seed: int = 1,
                 loads_kg: dict[str, float] | None = None,
                 heartbeat_watchdog_s: float = 0.0) -> None:
        self.cfg = cfg
        self.plant = EmulatedPlant(cfg, seed, loads_kg, heartbeat_watchdog_s)
        self.modbus: dict[str, EmulatedModbusDevice] = {}
        self.encoders: dict[str, EmulatedEncoder] = {}  # by "driver.channel"
        self.nidaq: dict[str, EmulatedDaq] = {}  # by driver
        self._daq_servers: list[DaqServer] = []
        self.endpoints: dict[str, str] = {}
        self.notices: list[str] = []
        self._ptys: list[PtyPair] = []
        self._servers: list[ModbusServer] = []
        self._networks: list[canopen.Network] = []
        self._socketcand: list[SocketcandServer] = []
        self._loop = asyncio.new_event_loop()
        self._loop_thread = threading.Thread(target=self._loop.run_forever,
                                             name="emu-asyncio", daemon=True)
        self.server_lateness = Lateness()  # of the Modbus servers' event loop

    # -- life cycle -----------------------------------------------------------------------
    def start(self) -> None:
        self.plant.start()
        self._loop_thread.start()
        asyncio.run_coroutine_threadsafe(_watch_lag(self.server_lateness), self._loop)
        try:
            for drv in self.cfg.rig.drivers:
                if drv.type == "modbus":
                    self._start_modbus(drv.name, drv.options)
                elif drv.type == "canopen-encoder":
                    self._start_can(drv.name, drv.options)
                elif drv.type == "nidaqmx":
                    self._start_nidaq(drv.name, drv.options)
                elif drv.type != "sim":
                    self.notices.append(f"driver {drv.name!r} of type {drv.type!r} is not "
                                        "emulated")
        except BaseException:
            self.stop()
            raise
        for lateness in self._latenesses():  # from here on the devices serve
            lateness.reset()

    def stop(self) -> None:
        for daq in self._daq_servers:
            daq.stop()
        for enc in self.encoders.values():
            enc.stop()
        for net in self._networks:
            if net.bus is not None:  # the nodes' heartbeats: python-can's own threads
                net.bus.stop_all_periodic_tasks()
        # none may send on the bus once it is closed
        _join_cyclic_senders([p.host for p in self._ptys], CYCLIC_JOIN_S)
        for server in self._socketcand:
            server.stop()
        for net in self._networks:
            with contextlib.suppress(Exception):
                net.disconnect()
        if self._loop_thread.is_alive():
            for dev in self.modbus.values():
                self._loop.call_soon_threadsafe(dev.stop_watchdog)
            for srv in self._servers:
                with contextlib.suppress(Exception):
                    asyncio.run_coroutine_threadsafe(srv.shutdown(), self._loop).result(5.0)
            with contextlib.suppress(Exception):
                self._run(_cancel_all())
            self._loop.call_soon_threadsafe(self._loop.stop)
            self._loop_thread.join(5.0)
        for p in self._ptys:
            p.close()
        self.plant.stop()

    def _latenesses(self) -> list[Lateness]:
        return [self.plant.lateness, self.server_lateness,
                *(e.lateness for e in self.encoders.values()),
                *(d.lateness for d in self.nidaq.values())]

    def lateness(self) -> dict[str, dict[str, float]]:
        """How late each timed part of the emulator woke, worst and count (`Lateness`):
        a device late by more than its signal's timeout makes a stale fault by itself."""
        out = {"physics": self.plant.lateness.summary()}
        for name, daq in self.nidaq.items():
            out[name] = daq.lateness.summary()
        if self.modbus:
            out["modbus_servers"] = self.server_lateness.summary()
        for name, enc in self.encoders.items():
            out[name] = enc.lateness.summary()
        return out

    def _run(self, coro: Coroutine[object, object, _T]) -> _T:
        return asyncio.run_coroutine_threadsafe(coro, self._loop).result(10.0)

    # -- devices ----------------------------------------------------------------------------
    def _start_modbus(self, name: str, o: ModbusOptions) -> None:
        plant = self.plant
        dev = EmulatedModbusDevice(
            o, source=lambda ch: plant.raw_input(name, ch),
            sink=lambda ch, v: plant.set_output(name, ch, v), label=name,
            sample_period_s=self.sample_period_s(name))
        self.modbus[name] = dev
        url = socket_url(o.serial_port) if o.transport == "rtu" else None
        if o.transport == "tcp":
            self._servers.append(self._run(serve_tcp(dev, loopback(name, o.host), o.port)))
            self.endpoints[name] = f"modbus tcp {o.host}:{o.port} id {o.device_id}"
        elif o.transport == "rtu-tcp" or url is not None:
            host, port = url or (o.host, o.port)
            self._servers.append(self._run(serve_rtu_tcp(dev, loopback(name, host), port)))
            self.endpoints[name] = f"modbus rtu over tcp {host}:{port} id {o.device_id}"
        else:
            pair = PtyPair(o.serial_port)
            self._ptys.append(pair)
            self._servers.append(self._run(serve_rtu(dev, pair.device, o.baud, o.parity,
                                                     o.stopbits, o.bytesize)))
            self.endpoints[name] = (f"modbus rtu {o.serial_port} (device end {pair.device}) "
                                    f"{o.baud} baud id {o.device_id}")

    def sample_period_s(self, driver: str) -> float:
        """The module samples as slowly as the config says its inputs are sampled (the
        longest `sample_period_s` of the signals it carries; 0: at every request)."""
        periods = [sig.sample_period_s for m in self.cfg.rig.muscles
                   for sig in (m.signals.pressure, m.signals.force, m.signals.length)
                   if sig.driver == driver and sig.sample_period_s is not None]
        return max(periods, default=0.0)

    def _start_can(self, name: str, o: CanEncoderOptions) -> None:
        import canopen

        from pamd.emulate.canopen_node import EmulatedEncoder

        net = canopen.Network()
        # the notifier thread's idle wake-up: closing the network waits for it (1 s by
        # default); frames are delivered as they come either way
        net.NOTIFIER_CYCLE = 0.05
        if o.interface == "socketcand":
            local = f"pamd-emu-{name}-{os.getpid()}-{id(self)}"
            net.connect(interface="virtual", channel=local)
            server = SocketcandServer(loopback(name, o.host), o.port, o.channel, local)
            server.start()
            self._socketcand.append(server)
            where = f"socketcand {o.host}:{o.port} bus {o.channel}"
        elif o.interface == "serial":
            pair = PtyPair(o.channel)
            self._ptys.append(pair)
            net.connect(interface="serial", channel=pair.device, timeout=0.01)
            where = f"python-can serial {o.channel} (device end {pair.device})"
        elif o.interface == "virtual":
            net.connect(interface="virtual", channel=o.channel)
            where = f"python-can virtual {o.channel} (this process only)"
        else:
            raise RuntimeError(f"driver {name!r}: the emulator serves CAN over the "
                               "'socketcand', 'serial' (pty pair) or 'virtual' interface, "
                               f"not {o.interface!r}")
        self._networks.append(net)
        plant = self.plant
        for e in o.encoders:
            def counts(e: EncoderNode = e) -> int:
                mm = plant.raw_input(name, e.name)
                return 0 if mm is None else round((mm - e.offset_mm) / e.mm_per_count)

            enc = EmulatedEncoder(net, e.node_id, counts)
            enc.start()
            self.encoders[f"{name}.{e.name}"] = enc
        if o.frames:
            self.notices.append(f"driver {name!r}: raw CAN frames are not emulated")
        self.endpoints[name] = (f"canopen {where}, nodes "
                                f"{', '.join(str(e.node_id) for e in o.encoders)}")

    def _start_nidaq(self, name: str, o: NidaqOptions) -> None:
        """An NI gRPC Device Server on the driver's (loopback) `server`, with one emulated
        device: the product the options name (a USB-6211 if none), its channels wired to
        the plant by the driver's channel names."""
        try:
            from pamd.emulate.nidaq_server import DaqServer
        except ImportError as exc:
            raise RuntimeError(f"driver {name!r}: NI's nidaqmx[grpc] is not installed ({exc}): "
                               "pip install 'pamd[nidaq]'") from None

        if not o.server:
            raise RuntimeError(f"driver {name!r}: the emulator serves an nidaqmx device through "
                               "an NI gRPC Device Server: set its `server` (127.0.0.1:PORT)")
        host, _, port = o.server.rpartition(":")
        product = PRODUCTS.get(o.product or USB_6211.name)
        if product is None:
            raise RuntimeError(f"driver {name!r}: the emulator plays {', '.join(PRODUCTS)}, "
                               f"not {o.product!r}")
        by_physical = {a.physical_channel.lower(): a.name for a in o.analog_inputs}
        by_physical.update({e.counter.lower(): e.name for e in o.encoders})
        by_physical.update({a.physical_channel.lower(): a.name for a in o.analog_outputs})
        by_physical.update({d.line.lower(): d.name for d in (*o.digital_inputs,
                                                             *o.digital_outputs)})
        plant = self.plant

        def source(physical: str) -> float | None:
            channel = by_physical.get(physical)
            return None if channel is None else plant.raw_input(name, channel)

        def sink(physical: str, value: float) -> None:
            channel = by_physical.get(physical)
            if channel is not None:
                plant.set_output(name, channel, value)

        device = NidaqDriver(name, o).device
        daq = EmulatedDaq(device, product, source, sink)
        server = DaqServer({device: daq}, loopback(name, host), int(port))
        server.start()
        self.nidaq[name] = daq
        self._daq_servers.append(server)
        self.endpoints[name] = f"NI gRPC Device Server {server.address}, {device} ({product.name})"
