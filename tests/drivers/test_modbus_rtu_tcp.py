"""The `modbus` driver's RTU frames over TCP against the emulator's server (no pty
between): transport `rtu-tcp` (pymodbus's TCP client with its RTU framer, as for an
RS-485 device server) and transport `rtu` on a pyserial `socket://` URL (pymodbus's
serial client through pyserial's socket port): float32 and int32 inputs, a coil
write, the line's claim. A server that goes away and comes back, an absent one:
test_contract.py."""

from __future__ import annotations

import time

import pytest
from pamd.drivers.modbus import ModbusDriver, ModbusOptions
from pamd.drivers.modbus_map import ModbusPoint

from pamd.emulate.modbus_device import EmulatedModbusDevice, serve_rtu_tcp
from pamd.emulate.testing import AioThread, free_port, wait_until

POINTS = dict(
    inputs=(ModbusPoint(name="force", function="input", address=0, type="float32", unit="N"),
            ModbusPoint(name="count", function="input", address=2, type="int32",
                        word_order="little", unit="")),
    outputs=(ModbusPoint(name="tare", function="coil", address=0, unit=""),))


def options(port: int, url: bool, timeout_s: float = 0.05) -> ModbusOptions:
    where = (dict(transport="rtu", serial_port=f"socket://127.0.0.1:{port}") if url
             else dict(transport="rtu-tcp", host="127.0.0.1", port=port))
    return ModbusOptions(baud=115200, device_id=7, timeout_s=timeout_s, poll_period_s=0.0,
                         fault_after_s=4 * timeout_s, reconnect_max_s=0.2,
                         **where, **POINTS)  # type: ignore[arg-type]


@pytest.mark.parametrize("url", [False, True], ids=["rtu-tcp", "socket-url"])
def test_rtu_frames_over_tcp_round_trip(aio: AioThread, url: bool) -> None:
    port = free_port()
    shown: dict[str, float] = {"force": 294.3, "count": -7}
    got: dict[str, float] = {}
    # Every request answered, none lost: the emulator answers from an asyncio thread of
    # this test's busy process (three pytest workers on two cores), which a 50 ms reply
    # deadline sometimes missed; what is checked here is the frames, not the latency
    opts = options(port, url, timeout_s=0.5)
    dev = EmulatedModbusDevice(opts, shown.get, got.__setitem__)
    server = aio.run(serve_rtu_tcp(dev, "127.0.0.1", port))
    d = ModbusDriver("lc", opts)
    d.open(time.monotonic)
    try:
        assert wait_until(lambda: d.in_values[0] == pytest.approx(294.3, abs=1e-4))
        assert d.in_values[1] == -7.0
        d.write(0, 1.0)
        assert wait_until(lambda: got.get("tare") == 1.0)
        shown["force"] = 100.0
        assert wait_until(lambda: d.in_values[0] == pytest.approx(100.0))
        h = d.health()
        assert h.ok and h.counters["connects"] == 1 and "timeouts" not in h.counters
    finally:
        d.close()
        aio.run(server.shutdown())


def test_the_line_behind_a_device_server_is_claimed_and_timed() -> None:
    port = free_port()
    over_tcp = ModbusDriver("lc", options(port, url=False))
    assert over_tcp.claims() == (f"Modbus RTU line at 127.0.0.1:{port}",)
    assert f"rtu-tcp 127.0.0.1:{port}" in over_tcp.describe()
    url = ModbusDriver("lc", options(port, url=True))
    assert url.claims() == (f"serial port socket://127.0.0.1:{port}",)
    # a lost reply costs the wait, the retry's frames on the RS-485 line and the poll
    tcp = ModbusDriver("io", ModbusOptions(transport="tcp", timeout_s=0.05, poll_period_s=0.0,
                                           **POINTS))  # type: ignore[arg-type]
    assert over_tcp.lost_reply_s() == pytest.approx(url.lost_reply_s())
    assert over_tcp.lost_reply_s() > tcp.lost_reply_s() == pytest.approx(0.05)
