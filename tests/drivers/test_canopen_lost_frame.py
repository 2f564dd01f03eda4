"""The `canopen-encoder` driver over python-can's `serial` interface (the emulated
rig's CAN link) when frames are cut short, garbled, late or missing: the test writes
the bytes of the encoder's frames itself into a pty the driver reads.

Both ways: a frame that cannot be read (cut short by the read timeout, a bad
delimiter) costs that frame, not the link (no re-open, no fault), and frames that
come late and in bursts raise no fault; a node that falls silent is still found, not
before its stated time (`position_timeout_s` + `fault_after_s`, on the driver's own
clock), and garbage that never stops is a lost link (re-opened after `lost_after`
failed reads in a row).
"""

from __future__ import annotations

import os
import struct
import time
import tty
from collections.abc import Iterator

import pytest
from pamd.drivers.can_frames import TPDO1_BASE, EncoderNode
from pamd.drivers.canopen_encoder import CanEncoderDriver, CanEncoderOptions, link_gone

from pamd.emulate.testing import wait_until

NODE = 3
POSITION_TIMEOUT_S = 0.2
FAULT_AFTER_S = 0.3


def frame(counts: int, can_id: int = TPDO1_BASE + NODE) -> bytes:
    """One frame as python-can's serial interface puts it on the wire."""
    data = struct.pack("<i", counts)
    return (b"\xaa" + struct.pack("<I", 0) + bytes([len(data)]) + struct.pack("<I", can_id)
            + data + b"\xbb")


class Watch(CanEncoderDriver):
    """The driver, noting on its own clock how long the node had been silent when it
    set `fault`."""

    silent_at_fault_s: float | None = None

    def failing(self, what: str) -> None:
        super().failing(what)
        if self.fault is not None and self.silent_at_fault_s is None:
            self.silent_at_fault_s = time.monotonic() - self.nodes[0].last_pdo


class Wire:
    """A pty: the driver reads its far end, the test writes frames into this one."""

    def __init__(self, **options: object) -> None:
        self.fd, slave = os.openpty()
        tty.setraw(slave)
        self.path = os.ttyname(slave)
        self._slave = slave
        node = EncoderNode(name="pos", node_id=NODE, configure=False, heartbeat_ms=0,
                           position_timeout_s=POSITION_TIMEOUT_S)
        self.driver = Watch("enc", CanEncoderOptions(
            interface="serial", channel=self.path, encoders=(node,),
            fault_after_s=FAULT_AFTER_S, reconnect_max_s=0.2, **options))  # type: ignore[arg-type]
        self.counts = 0

    def send(self, n: int = 1) -> None:
        for _ in range(n):
            self.counts += 1
            os.write(self.fd, frame(self.counts))

    def positions(self) -> int:
        return self.driver.health().counters.get("positions", 0)

    def drain(self) -> None:
        """Throw away what the driver sent (its NMT start)."""
        os.set_blocking(self.fd, False)
        try:
            while os.read(self.fd, 4096):
                pass
        except (BlockingIOError, OSError):
            pass
        finally:
            os.set_blocking(self.fd, True)

    def stream(self, until: int) -> None:
        """Frames every millisecond until the driver has read `until` positions."""
        deadline = time.monotonic() + 30.0
        while self.positions() < until and time.monotonic() < deadline:
            self.send()
            time.sleep(0.001)

    def close(self) -> None:
        self.driver.close()
        os.close(self.fd)
        os.close(self._slave)


@pytest.fixture
def wire() -> Iterator[Wire]:
    w = Wire()
    w.driver.open(time.monotonic)
    assert wait_until(lambda: w.driver.health().counters.get("nodes_started", 0) == 1)
    w.drain()
    yield w
    w.close()


def test_a_cut_frame_costs_that_frame_not_the_link(wire: Wire) -> None:
    d = wire.driver
    wire.stream(until=50)
    for k in range(1, 3):  # two frames cut apart, each followed by good frames
        os.write(wire.fd, frame(0)[:3])  # the start of a frame, and then nothing
        assert wait_until(lambda k=k: d.health().counters.get("failed_reads", 0) == k)
        wire.stream(until=wire.positions() + 50)
    c = d.health().counters
    assert c["bus_opens"] == 1 and c.get("bus_errors", 0) == 0  # the link was kept
    assert d.fault is None and d.connected
    assert wait_until(lambda: d.in_values[0] == pytest.approx(wire.counts * 0.01))


def test_a_garbled_frame_is_skipped(wire: Wire) -> None:
    d = wire.driver
    wire.stream(until=50)
    os.write(wire.fd, frame(0)[:-1] + b"\x00")  # a bad delimiter
    wire.stream(until=wire.positions() + 50)
    c = d.health().counters
    assert c.get("failed_reads", 0) == 1 and c["bus_opens"] == 1 and d.fault is None


def test_late_bursty_frames_raise_no_fault(wire: Wire) -> None:
    """A node whose frames wait and then come 60 at a time (a busy PC or gateway):
    each gap (60 ms) well inside position_timeout_s, so healthy; the stamps' jitter
    says how long a frame of the burst may have waited."""
    d = wire.driver
    wire.stream(until=20)
    for _ in range(10):
        time.sleep(0.06)
        wire.send(60)
    assert wait_until(lambda: wire.positions() >= 20 + 600)
    assert d.fault is None and d.health().counters.get("failed_reads", 0) == 0
    assert d.in_jitter_s[0] >= 0.0


def test_a_silent_node_is_found_not_before_its_stated_time(wire: Wire) -> None:
    d = wire.driver
    wire.stream(until=50)
    # the node falls silent (the cable cut): nothing more on the wire
    assert wait_until(lambda: d.fault is not None)
    assert "node 3 (pos) sends no position" in d.fault
    assert d.silent_at_fault_s is not None
    assert d.silent_at_fault_s >= POSITION_TIMEOUT_S + FAULT_AFTER_S
    wire.stream(until=wire.positions() + 20)  # it comes back: the fault clears by itself
    assert wait_until(lambda: d.fault is None)


def test_garbage_that_never_stops_is_a_lost_link() -> None:
    w = Wire(lost_after=3)
    try:
        w.driver.open(time.monotonic)
        assert wait_until(lambda: w.driver.health().counters.get("nodes_started", 0) == 1)
        bad = frame(0)[:-1] + b"\x00"
        assert wait_until(lambda: (os.write(w.fd, bad * 3) > 0
                                   and w.driver.health().counters.get("bus_errors", 0) >= 1))
        c = w.driver.health().counters
        assert c["failed_reads"] >= 2 and c["bus_opens"] >= 1
    finally:
        w.close()


def test_link_gone_tells_a_port_error_from_a_bad_frame() -> None:
    try:
        try:
            raise OSError(5, "Input/output error")
        except OSError as exc:
            raise RuntimeError("could not read from serial") from exc
    except RuntimeError as chained:
        assert link_gone(chained)
    assert not link_gone(struct.error("unpack requires a buffer of 4 bytes"))
    assert not link_gone(ValueError("invalid delimiter byte while reading message: 0"))
