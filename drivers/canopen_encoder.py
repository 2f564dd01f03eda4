"""The `canopen-encoder` driver: CiA 406 encoders (and raw CAN frames) on one
python-can bus.

Per encoder node the driver's thread configures TPDO1 to carry the position
(0x6004) on an event timer and sets the heartbeat time (0x1017) by SDO, starts
the node (NMT start), then publishes every position frame, scaled counts -> mm and
stamped with the loop's clock on arrival (CiA 406 carries no sample time) and a
jitter: how long the frame may have waited in the socket (`ArrivalWindow`: since the
thread last found the bus idle; a backlog read after the process was held up gets
the whole hold). A frame on the position address of a node that is not configured
(its configuration failed, or it rebooted and is being configured again) is counted
(`unconfigured_frames`) and ignored: the driver did not ask that node for positions,
so what the frame carries is no position. It watches the heartbeat: a silent node,
one that stops sending positions, one that reports an emergency (EMCY) or sends
frames of the wrong length is counted and named in `health()`, and when that lasts
`fault_after_s` it sets `fault` (safe state). A node that reboots (boot-up message)
is configured and started again; the fault clears when it is healthy and the
operator resets. `preset_position()` sets the encoder's own datum through
the preset object 0x6003 (for `home`), without blocking the caller.

Raw frames (`frames:`) read a field of any CAN frame for devices that are not
CANopen. Interfaces: anything python-can opens (`socketcan`, `pcan`, ...;
`socketcand`, a CAN bus carried over TCP, `host`/`port`: the emulated rig's bus;
`serial` over a pty pair, the emulated rig's older link; `virtual` in one process for
tests). A socketcand server that closes the connection is a lost link: the bus is
re-opened and the nodes configured again.

This module owns the bus (open, receive, send, dispatch, the driver's health); the
nodes' configuration, heartbeats, emergencies and presets are `drivers/canopen_nodes.py`,
the frames' layouts `drivers/can_frames.py`.
"""

from __future__ import annotations

import contextlib
import logging
import math
import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from pamd.drivers import Channel, serial_port_claim
from pamd.drivers.can_frames import (
    EMCY_BASE,
    HEARTBEAT_BASE,
    TPDO1_BASE,
    EncoderNode,
    RawFrame,
    raw_frame_value,
)
from pamd.drivers.canopen_nodes import EncoderNodes, NodeState
from pamd.drivers.device import ArrivalWindow, Backoff, ThreadedDriver
from pamd.drivers.socketcand_link import one_connect_attempt, server_closed

from pamd.wire.errors import DriverError
from pamd.wire.schema.engine import spec

BAD_FRAME_HOLD_S = 0.05  # a bad frame counts as a failing cycle this long


@dataclass(frozen=True, kw_only=True)
class CanEncoderOptions:
    """Options of the `canopen-encoder` driver."""

    interface: str = spec("socketcan", "python-can interface (socketcan, pcan, kvaser, "
                          "socketcand, serial, virtual, ...).")
    channel: str = spec("can0", "python-can channel (can0; a serial device or pyserial URL "
                        "for 'serial'; the bus's name on the server for 'socketcand').")
    host: str = spec("", "socketcand: the server's address (a CAN bus carried over TCP; "
                     "the emulated rig's, or a socketcand daemon on a CAN gateway).")
    port: int = spec(29536, "socketcand: the server's TCP port (socketcand's default 29536).",
                     min=1, max=65535)
    connect_timeout_s: float = spec(
        1.0, "socketcand: longest wait for the server to accept and greet (one attempt, "
        "then the driver backs off and retries); it stays on the link's socket, so a read "
        "or send the server does not take fails after it instead of hanging.",
        unit="s", gt=0.0, max=30.0)
    bitrate: int = spec(500000, "Bus bit rate (ignored by serial and virtual).", unit="bit/s",
                        min=10000, max=1000000)
    sdo_timeout_s: float = spec(0.2, "Wait this long for an SDO answer.", unit="s", gt=0.0)
    recv_timeout_s: float = spec(0.005, "Longest wait for a frame before the thread checks "
                                 "its timers.", unit="s", gt=0.0, max=0.1)
    fault_after_s: float = spec(0.3, "Failure lasting this long sets the driver's fault.",
                                unit="s", gt=0.0)
    lost_after: int = spec(3, "Failed reads in a row (a garbled or cut frame) or SDO requests "
                           "unanswered in a row that mean the link is lost (the bus is "
                           "re-opened; an SDO is given up); fewer are skipped or re-sent at "
                           "once: one lost frame or reply costs one retry.", min=1, max=20)
    reconnect_min_s: float = spec(0.05, "First retry delay (bus or node configuration).",
                                  unit="s", gt=0.0)
    reconnect_max_s: float = spec(2.0, "Longest retry delay.", unit="s", gt=0.0)
    encoders: tuple[EncoderNode, ...] = spec((), "CiA 406 encoder nodes on this bus.")
    frames: tuple[RawFrame, ...] = spec((), "Values in raw CAN frames (not CANopen).")


def link_gone(exc: BaseException) -> bool:
    """True if a receive error means the link itself failed (an OS or port error
    anywhere in its chain: the adapter unplugged, the port closed), False for a frame
    that could not be decoded (cut short, a bad delimiter or length)."""
    seen: set[int] = set()
    e: BaseException | None = exc
    while e is not None and id(e) not in seen:
        if isinstance(e, OSError):  # serial.SerialException is one too
            return True
        seen.add(id(e))
        e = e.__cause__ or e.__context__
    return False


class CanEncoderDriver(ThreadedDriver):
    """CiA 406 encoders and raw CAN values on one bus."""

    options_type = CanEncoderOptions

    def __init__(self, name: str, options: CanEncoderOptions | None = None) -> None:
        o = options if options is not None else CanEncoderOptions()
        names = [e.name for e in o.encoders] + [f.name for f in o.frames]
        problems = []
        if len(set(names)) != len(names):
            problems.append("channel names must be unique")
        ids = [e.node_id for e in o.encoders]
        if len(set(ids)) != len(ids):
            problems.append("node ids must be unique")
        if not names:
            problems.append("needs at least one encoder or frame")
        if o.interface == "socketcand" and not o.host:
            problems.append("interface socketcand needs host (the server's address)")
        if o.interface == "udp_multicast":
            problems.append("interface udp_multicast sends off this machine; use socketcan, "
                            "serial or virtual")
        if problems:
            raise DriverError(f"canopen-encoder driver {name!r}: " + "; ".join(problems))
        super().__init__(name, o)
        self.fault_after_s = o.fault_after_s
        self._window = ArrivalWindow()
        self.preset_generation = self.preset_counts  # the protocol's name for it
        self.encoder_nodes = EncoderNodes(o.encoders, o.sdo_timeout_s, o.recv_timeout_s,
                                          o.lost_after, self.preset_generation)
        self.nodes = self.encoder_nodes.nodes
        self._by_cob: dict[int, tuple[str, NodeState]] = {}
        for n in self.nodes:
            self._by_cob[TPDO1_BASE + n.id] = ("pdo", n)
            self._by_cob[HEARTBEAT_BASE + n.id] = ("hb", n)
            self._by_cob[EMCY_BASE + n.id] = ("emcy", n)
        self._raw: dict[tuple[int, bool], list[tuple[int, RawFrame]]] = {}
        for k, f in enumerate(o.frames):
            self._raw.setdefault((f.can_id, f.extended), []).append((len(self.nodes) + k, f))
        self._bus: Any = None  # Any: a python-can bus (imported on the driver's thread)
        self._bad_t = -math.inf
        self._bad_msg = ""
        self._failed_reads = 0  # receive errors in a row (lost_after: the link is lost)

    # -- Driver protocol ----------------------------------------------------------------
    def channels(self) -> Sequence[Channel]:
        o: CanEncoderOptions = self.options
        return ([Channel(e.name, "in", "mm") for e in o.encoders]
                + [Channel(f.name, "in", f.unit) for f in o.frames])

    def write(self, index: int, value: float) -> None:
        raise DriverError(f"{self.describe()} has no outputs")

    def is_absolute(self, index: int) -> bool:
        o: CanEncoderOptions = self.options
        if index < len(o.encoders):
            return o.encoders[index].absolute
        return o.frames[index - len(o.encoders)].absolute

    def claims(self) -> tuple[str, ...]:
        """The bus (the nodes are configured through it); python-can's `serial`
        interface is a serial port; `virtual` lives inside one process."""
        o: CanEncoderOptions = self.options
        if o.interface == "virtual":
            return ()
        if o.interface in ("serial", "slcan"):
            return serial_port_claim(o.channel)
        if o.interface == "socketcand":
            return (f"CAN channel socketcand:{o.host.lower()}:{o.port}:{o.channel}",)
        return (f"CAN channel {o.interface}:{o.channel}",)

    def describe(self) -> str:
        o: CanEncoderOptions = self.options
        where = f" at {o.host}:{o.port}" if o.interface == "socketcand" else ""
        return f"canopen-encoder {self.name!r} ({o.interface} {o.channel}{where})"

    def preset_input(self, index: int, raw_value: float) -> bool:
        """`home` through the encoder's preset object (0x6003); raw frames cannot."""
        if index >= len(self.nodes):
            return False
        self.preset_position(index, raw_value)
        return True

    def preset_position(self, index: int, position_mm: float) -> None:
        """Make encoder `index` read `position_mm` from now on (0x6003), done by the
        driver's thread; `preset_generation[index]` counts the presets applied."""
        if index >= len(self.nodes):
            raise DriverError(f"{self.describe()}: channel {index} is not a CANopen encoder")
        e = self.nodes[index].spec
        counts = round((position_mm - e.offset_mm) / e.mm_per_count)
        self.encoder_nodes.queue_preset(index, counts)

    # -- the I/O thread -------------------------------------------------------------------
    def _open_bus(self) -> bool:
        import can

        o: CanEncoderOptions = self.options
        kwargs: dict[str, Any] = {}  # Any: can.Bus keyword arguments, per interface
        link: contextlib.AbstractContextManager[None] = contextlib.nullcontext()
        where = ""  # the link, in an error
        if o.interface == "serial":
            kwargs["timeout"] = o.recv_timeout_s
        elif o.interface == "socketcand":
            # its client logs a warning for every frame split across two reads (normal
            # on TCP); the driver counts what matters
            logging.getLogger("can.interfaces.socketcand").setLevel(logging.ERROR)
            kwargs.update(host=o.host, port=o.port, tcp_tune=True)  # TCP_NODELAY
            link = one_connect_attempt(o.connect_timeout_s)  # drivers/socketcand_link.py
            where = f"socketcand server {o.host}:{o.port}: "
        elif o.interface != "virtual":
            kwargs["bitrate"] = o.bitrate
        try:
            with link:
                self._bus = can.Bus(interface=o.interface, channel=o.channel, **kwargs)
        except Exception as exc:  # noqa: BLE001 - missing adapter, bad channel: retry
            self.error("bus_open_failures", f"cannot open the bus: {where}{exc}")
            return False
        self.connected = True
        self.count("bus_opens")
        return True

    @property
    def bus_open(self) -> bool:
        return self._bus is not None

    def release(self) -> None:
        bus, self._bus = self._bus, None
        self.connected = False
        if bus is not None:
            with contextlib.suppress(Exception):
                bus.shutdown()

    def run(self) -> None:
        o: CanEncoderOptions = self.options
        backoff = Backoff(o.reconnect_min_s, o.reconnect_max_s)
        mono = time.monotonic
        last_check = 0.0
        while not self.stopping.is_set():
            if self._bus is None:
                if not self._open_bus():
                    self.failing(f"cannot open the CAN bus ({self.recent_errors[-1]})")
                    self.stopping.wait(backoff.next())
                    continue
                backoff.reset()
            self.encoder_nodes.service(self, mono())
            self.receive(o.recv_timeout_s)
            now = mono()
            if now - last_check >= 0.01:
                last_check = now
                problem = self._check(now)
                if problem is None:
                    self.healthy()
                else:
                    self.failing(problem)
        self.release()

    def receive(self, timeout_s: float) -> Any:  # Any: python-can's Message, or None
        """Read one frame (waiting at most `timeout_s`) and dispatch it."""
        bus = self._bus
        if bus is None:
            return None
        window = self._window
        window.before_read(self.clock())
        try:
            msg = bus.recv(timeout_s)
            window.after_read(self.clock(), msg is not None)
        except Exception as exc:  # noqa: BLE001 - a broken link or garbage on the wire
            self._failed_reads += 1
            text = f"{type(exc).__name__}: {exc}" if str(exc) else type(exc).__name__
            if link_gone(exc) or self._failed_reads >= self.options.lost_after:
                self.error("bus_errors", f"receive failed ({self._failed_reads} in a row): "
                           f"{text}")
                self.release()
                self._failed_reads = 0
                return None
            # a frame cut short or garbled (python-can's serial interface reads a frame
            # byte by byte with the read timeout): that frame is lost, the link is not
            self.count("failed_reads")
            self.bad(f"a frame could not be read ({text}); skipped", ())
            return None
        self._failed_reads = 0
        if msg is not None:
            self._dispatch(msg)
        elif self.options.interface == "socketcand" and server_closed(bus):
            # python-can's client reads nothing from a closed connection without a word
            # (and spins until its timeout): re-open, and configure the nodes again (the
            # server, a gateway or the emulator, may have restarted with them)
            self.error("bus_errors", "the socketcand server closed the connection")
            self.release()
            self.encoder_nodes.reconfigure_all()
        return msg

    def send(self, can_id: int, data: bytes) -> bool:
        import can

        bus = self._bus
        if bus is None:
            return False
        try:
            bus.send(can.Message(arbitration_id=can_id, data=data, is_extended_id=False))
        except Exception as exc:  # noqa: BLE001 - a full queue, a broken link
            self.error("send_errors", f"send of 0x{can_id:03X} failed: {exc}")
            return False
        return True

    def _dispatch(self, msg: Any) -> None:  # Any: python-can's Message (untyped)
        if msg.is_error_frame:
            self.count("error_frames")
            return
        cid, data = msg.arbitration_id, bytes(msg.data)
        if not msg.is_extended_id and self.encoder_nodes.take_sdo_answer(cid, data):
            return
        raw = self._raw.get((cid, bool(msg.is_extended_id)))
        if raw is not None:
            now = self.clock()
            jitter = self._window.jitter_s(now)
            for idx, f in raw:
                v = raw_frame_value(f, data)
                if v is None:
                    self.bad(f"frame 0x{cid:X} for {f.name} has {len(data)} bytes, needs "
                              f"{f.byte_offset + f.length}", (f.name,))
                else:
                    self.stamp(idx, v, now, jitter)
            self.count("frames")
            return
        hit = None if msg.is_extended_id else self._by_cob.get(cid)
        if hit is None:
            self.count("ignored_frames")
            return
        frame, n = hit
        if frame == "pdo":
            if n.needs_config:  # not configured (failed, or rebooted since): whatever
                self.count("unconfigured_frames")  # sends on its position address is
                return  # not a position this driver asked for (CiA 301: TPDO1 unset)
            if len(data) < 4:
                self.bad(f"{n.label}: position frame of {len(data)} bytes, needs 4",
                          (n.spec.name,))
                return
            counts = int.from_bytes(data[:4], "little", signed=n.spec.signed)
            n.last_pdo = time.monotonic()
            now = self.clock()
            self.stamp(n.index, counts * n.spec.mm_per_count + n.spec.offset_mm, now,
                       self._window.jitter_s(now))
            self.count("positions")
        elif frame == "hb":
            self.encoder_nodes.heartbeat(self, n, data)
        else:
            self.encoder_nodes.emergency(self, n, data)

    def bad(self, message: str, names: tuple[str, ...]) -> None:
        self._bad_t = time.monotonic()
        self._bad_msg = self.error("bad_frames", message, names)

    def _check(self, now: float) -> str | None:
        """The first problem of any node, or a recent bad frame, or None."""
        if self._bus is None:
            return "CAN bus closed after an error (reopening)"
        last = self.recent_errors[-1] if self.recent_errors else ""
        problem = self.encoder_nodes.problem(now, self.counters.get("config_failures", 0),
                                             last)
        if problem is not None:
            return problem
        if now - self._bad_t < BAD_FRAME_HOLD_S:
            return self._bad_msg
        return None
