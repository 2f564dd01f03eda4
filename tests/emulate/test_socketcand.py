"""The emulator's socketcand server against python-can's own `socketcand` client (the
interface the daemon's CAN driver opens): the handshake, frames both ways with 11- and
29-bit ids, a CAN bus's delivery (every other station sees a frame, the sender does
not), and what it refuses. The CAN driver's behaviour over it (SDO, NMT, a server that
goes away and comes back, an absent server): tests/drivers/test_contract.py; the whole
emulated rig over it: tests/drivers/test_daemon_emulated.py."""

from __future__ import annotations

import socket
import time
from collections.abc import Iterator

import can
import pytest

from pamd.emulate.socketcand import SocketcandServer, frame_text, parse_send
from pamd.emulate.testing import free_port, wait_until

RECV_S = 10.0  # generous: this machine is busy; a frame takes a fraction of a ms


@pytest.fixture
def server() -> Iterator[SocketcandServer]:
    s = SocketcandServer("127.0.0.1", free_port(), "can0",
                         f"pamd-cand-test-{time.monotonic_ns()}")
    s.start()
    yield s
    s.stop()


def client(s: SocketcandServer) -> can.BusABC:
    return can.Bus(interface="socketcand", host=s.host, port=s.port, channel="can0",
                   tcp_tune=True)


def first(bus: can.BusABC, can_id: int) -> can.Message:
    """The first frame of `can_id` (other stations' frames skipped), or fail."""
    deadline = time.monotonic() + RECV_S
    while time.monotonic() < deadline:
        msg = bus.recv(0.1)
        if msg is not None and msg.arbitration_id == can_id:
            return msg
    raise AssertionError(f"no frame 0x{can_id:X} within {RECV_S} s")


def test_frames_flow_both_ways_through_python_cans_client(server: SocketcandServer) -> None:
    devices = can.Bus(interface="virtual", channel=server.local_channel)  # the emulated nodes
    a, b = client(server), client(server)
    try:
        assert wait_until(lambda: len(server.clients) == 2)
        time.sleep(0.1)  # both past their raw-mode answer
        devices.send(can.Message(arbitration_id=0x185, data=b"\x01\x02\x03\x04",
                                 is_extended_id=False))
        for bus in (a, b):  # every station on the bus sees the device's frame
            msg = first(bus, 0x185)
            assert bytes(msg.data) == b"\x01\x02\x03\x04" and not msg.is_extended_id
            assert msg.timestamp == pytest.approx(time.time(), abs=RECV_S)
        a.send(can.Message(arbitration_id=0x1ABCDE0, data=b"\xff\x00", is_extended_id=True))
        got = devices.recv(RECV_S)
        assert got is not None and got.arbitration_id == 0x1ABCDE0 and got.is_extended_id
        assert bytes(got.data) == b"\xff\x00"
        msg = first(b, 0x1ABCDE0)  # the other client too ...
        assert msg.is_extended_id and bytes(msg.data) == b"\xff\x00"
        a.send(can.Message(arbitration_id=0x000, data=b"", is_extended_id=False))
        assert first(b, 0x000).dlc == 0  # an empty frame (an NMT-like id 0)
        assert a.recv(0.3) is None  # ... never the sender (a controller hears no echo)
        assert server.frames_in == 2
    finally:
        a.shutdown()
        b.shutdown()
        devices.shutdown()


def test_a_bus_the_server_does_not_have_is_refused_by_name(server: SocketcandServer) -> None:
    with pytest.raises(can.CanError, match="no such bus vcan7"):
        can.Bus(interface="socketcand", host=server.host, port=server.port, channel="vcan7")


def test_malformed_commands_get_an_error_and_the_connection_stays(
        server: SocketcandServer) -> None:
    with socket.create_connection((server.host, server.port), timeout=RECV_S) as raw:
        assert raw.recv(64) == b"< hi >"
        raw.sendall(b"< open can0 >")
        assert raw.recv(64) == b"< ok >"
        raw.sendall(b"< send 123 4 1 2 >")  # before raw mode: not served
        assert b"error" in raw.recv(128)
        raw.sendall(b"< rawmode >")
        assert raw.recv(64) == b"< ok >"
        raw.sendall(b"< send 123 4 1 2 >")  # 4 bytes announced, 2 given
        assert b"bad send" in raw.recv(128)
        raw.sendall(b"< bcmmode >")
        assert b"not served" in raw.recv(128)
        raw.sendall(b"< echo >")
        assert raw.recv(64) == b"< echo >"  # still served


def test_frame_words_round_trip() -> None:
    msg = can.Message(arbitration_id=0x7FF, data=b"\x0a\xb0", is_extended_id=False)
    assert frame_text(msg, 12.5) == "< frame 7FF 12.500000 0AB0 >"
    ext = can.Message(arbitration_id=0x1F, data=b"", is_extended_id=True)
    assert frame_text(ext, 0.0) == "< frame 0000001F 0.000000  >"
    back = parse_send(["7FF", "2", "a", "b0"])
    assert back.arbitration_id == 0x7FF and bytes(back.data) == b"\x0a\xb0"
    assert not back.is_extended_id
    assert parse_send(["0000001F", "0"]).is_extended_id
    for bad in ("800 0", "123 9 1 2 3 4 5 6 7 8 9", "12", "123 1 zz"):
        with pytest.raises(ValueError):
            parse_send(bad.split())
