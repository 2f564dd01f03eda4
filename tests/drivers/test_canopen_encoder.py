"""The `canopen-encoder` driver on python-can's `virtual` bus against canopen's
LocalNode playing a CiA 406 encoder: configuration by SDO, NMT start, scaling,
preset (home), rebooted / faulty nodes, wrong-length and raw frames (a silent or
missing node: the contract suite, test_contract.py)."""

from __future__ import annotations

import itertools
import time
from collections.abc import Iterator
from typing import Any

import can
import canopen
import pytest
from pamd.drivers.can_frames import EncoderNode, RawFrame, sdo_download, sdo_reply
from pamd.drivers.canopen_encoder import CanEncoderDriver, CanEncoderOptions

from pamd.emulate.canopen_node import EmulatedEncoder
from pamd.emulate.testing import wait_until
from pamd.wire.errors import DriverError

_ids = itertools.count()


class Bus:
    """A private virtual CAN channel with a canopen network on it."""

    def __init__(self) -> None:
        self.channel = f"pamd-enc-test-{next(_ids)}-{time.monotonic_ns()}"
        self.net = canopen.Network()
        # its notifier thread wakes every 0.05 s, not every 1 s, when no frame comes: the
        # bus's close waits for that wake-up (frames are delivered as they come either way)
        self.net.NOTIFIER_CYCLE = 0.05
        self.net.connect(interface="virtual", channel=self.channel)
        self.encoders: list[EmulatedEncoder] = []
        self.drivers: list[CanEncoderDriver] = []

    def encoder(self, node_id: int, physical: int = 0) -> EmulatedEncoder:
        e = EmulatedEncoder(self.net, node_id)
        e.physical = physical
        e.start()
        self.encoders.append(e)
        return e

    def driver(self, *nodes: EncoderNode, frames: tuple[RawFrame, ...] = (),
               **kw: Any) -> CanEncoderDriver:
        d = CanEncoderDriver("enc", CanEncoderOptions(interface="virtual", channel=self.channel,
                                                      encoders=nodes, frames=frames, **kw))
        d.open(time.monotonic)
        self.drivers.append(d)
        return d

    def close(self) -> None:
        for d in self.drivers:
            d.close()
        for e in self.encoders:
            e.stop()
        self.net.disconnect()


@pytest.fixture
def bus() -> Iterator[Bus]:
    b = Bus()
    yield b
    b.close()


def ready(d: CanEncoderDriver) -> bool:
    """Configured and running: positions and heartbeats arrive, no fault."""
    c = d.health().counters
    return d.fault is None and c.get("positions", 0) > 0 and c.get("heartbeats", 0) > 0


def node(node_id: int = 3, **kw: Any) -> EncoderNode:
    return EncoderNode(name=kw.pop("name", "pos"), node_id=node_id, **kw)


def test_configures_starts_and_scales(bus: Bus) -> None:
    enc = bus.encoder(3, physical=12345)
    d = bus.driver(node(3, event_timer_ms=2, heartbeat_ms=50, signed=True))
    assert wait_until(lambda: d.in_values[0] == pytest.approx(123.45))
    sdo = enc.node.sdo
    assert sdo[0x1800][5].raw == 2 and sdo[0x1800][2].raw == 254
    assert sdo[0x1A00][1].raw == 0x60040020 and sdo[0x1017].raw == 50
    assert enc.node.nmt.state == "OPERATIONAL"
    enc.physical = -500  # signed counts: -5 mm
    assert wait_until(lambda: d.in_values[0] == pytest.approx(-5.0))
    t = time.monotonic()
    assert wait_until(lambda: d.in_stamps_s[0] > t)
    assert d.health().ok and d.health().counters["heartbeats"] > 0


def test_preset_sets_the_encoders_reference(bus: Bus) -> None:
    bus.encoder(4, physical=777)
    d = bus.driver(node(4, mm_per_count=0.01, offset_mm=0.0))
    assert wait_until(lambda: d.in_values[0] == pytest.approx(7.77))
    d.preset_position(0, 204.5)  # home: the muscle is 204.5 mm long now
    assert wait_until(lambda: d.preset_generation[0] == 1)
    assert wait_until(lambda: d.in_values[0] == pytest.approx(204.5))
    with pytest.raises(DriverError):
        bus.driver(frames=(RawFrame(name="r", can_id=0x300),)).preset_position(0, 1.0)


def test_rebooted_node_is_configured_again(bus: Bus) -> None:
    enc = bus.encoder(6, physical=100)
    d = bus.driver(node(6, heartbeat_ms=20))
    assert wait_until(lambda: d.health().counters.get("nodes_started") == 1 and
                      d.health().counters.get("positions", 0) > 0)
    enc.boot()  # power cycle: configuration lost, PRE-OPERATIONAL, boot-up message
    assert wait_until(lambda: d.health().counters.get("nodes_started") == 2)
    assert wait_until(lambda: enc.node.nmt.state == "OPERATIONAL")
    assert d.health().counters["node_boots"] == 1
    assert wait_until(lambda: d.fault is None)


def test_emergency_and_wrong_length_frames(bus: Bus) -> None:
    enc = bus.encoder(7, physical=42)
    # Silence is not what this test is about: heartbeat and position timeouts no busy
    # machine reaches, so the first problem the driver finds (and latches as its fault)
    # is the emergency, then the short frame (a starved encoder thread would otherwise
    # make it "silent" or "sends no position" first: the latched fault would name that).
    d = bus.driver(node(7, heartbeat_ms=20, heartbeat_timeout_s=5.0, position_timeout_s=5.0),
                   fault_after_s=0.1)
    assert wait_until(lambda: ready(d))
    enc.emergency(0x2310)
    assert wait_until(lambda: d.fault is not None and "0x2310" in d.fault)
    enc.emergency(0x0000)  # error reset
    assert wait_until(lambda: d.fault is None)
    enc.pdo_length = 2  # a broken frame: 2 bytes where 4 are mapped
    assert wait_until(lambda: d.fault is not None and "2 bytes" in d.fault)
    assert d.health().counters["errors.pos"] > 0
    enc.pdo_length = 4
    assert wait_until(lambda: d.fault is None)


def test_frames_from_a_node_whose_configuration_failed_are_never_positions(bus: Bus) -> None:
    """Issue 43: random frames on node 1's position address were read as lengths
    although its configuration had failed (the rig went IDLE on random data). The
    node refuses every configuration write here: what comes on its address is counted
    and ignored, the value stays unread (NaN), the node named as not configured. Once
    it takes its configuration, its frames are positions again (the other way)."""
    enc = bus.encoder(1, physical=500)
    enc.refuse_config = True
    d = bus.driver(node(1, heartbeat_ms=20), fault_after_s=0.1, sdo_timeout_s=0.2)
    tx = can.Bus(interface="virtual", channel=bus.channel)
    try:
        assert wait_until(lambda: d.health().counters.get("config_failures", 0) > 0)
        for k in range(50):  # random data on node 1's TPDO1 address (0x181)
            tx.send(can.Message(arbitration_id=0x181, data=(k * 7919).to_bytes(4, "little"),
                                is_extended_id=False))
        assert wait_until(lambda: d.health().counters.get("unconfigured_frames", 0) >= 50)
        assert d.in_values[0] != d.in_values[0]  # NaN: never read
        assert d.health().counters.get("positions", 0) == 0
        assert wait_until(lambda: d.fault is not None and "not configured" in d.fault)
        enc.refuse_config = False  # the node takes its configuration: positions again
        assert wait_until(lambda: d.in_values[0] == pytest.approx(5.0), timeout_s=30.0)
    finally:
        tx.shutdown()


def test_raw_frames(bus: Bus) -> None:
    d = bus.driver(frames=(
        RawFrame(name="counter", can_id=0x321, byte_offset=2, length=2, signed=True,
                 byte_order="big", scale=0.5, unit="mm"),
        RawFrame(name="ext", can_id=0x18FF0001, extended=True, length=1, signed=False),
    ), fault_after_s=0.1)
    tx = can.Bus(interface="virtual", channel=bus.channel)
    try:
        # the driver opens its bus on its own thread; a virtual bus delivers a frame
        # only to the buses open when it is sent
        assert wait_until(lambda: d.connected)
        tx.send(can.Message(arbitration_id=0x321, data=b"\x00\x00\xff\xfe\x00",
                            is_extended_id=False))
        tx.send(can.Message(arbitration_id=0x18FF0001, data=b"\x07", is_extended_id=True))
        assert wait_until(lambda: d.in_values[0] == -1.0 and d.in_values[1] == 7.0)
        deadline = time.monotonic() + 20.0
        while d.fault is None and time.monotonic() < deadline:  # persistent garbage
            tx.send(can.Message(arbitration_id=0x321, data=b"\x00", is_extended_id=False))
            time.sleep(0.005)
        assert d.fault is not None and "counter" in d.fault
        assert d.health().counters["bad_frames"] > 0
    finally:
        tx.shutdown()


def test_sdo_helpers() -> None:
    req = sdo_download(0x6003, 0, 20450, 4)
    assert req[0] == 0x23 and int.from_bytes(req[4:], "little") == 20450
    ok, _ = sdo_reply(bytes([0x60, 0x03, 0x60, 0, 0, 0, 0, 0]), 0x6003, 0)
    assert ok
    ok, why = sdo_reply(bytes([0x80, 0x03, 0x60, 0, 0x00, 0x00, 0x02, 0x06]), 0x6003, 0)
    assert not ok and "0x06020000" in why and "does not exist" in why
