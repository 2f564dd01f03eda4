"""The `serial-line` driver: request/response over pyserial's loop:// (the request
comes back as the answer), streaming over a pty (os.openpty) with good lines,
malformed lines, bad checksums and overlong garbage (silence, recovery and a missing
port: the contract suite, test_contract.py)."""

from __future__ import annotations

import os
import time
from collections.abc import Iterator
from typing import Any

import pytest
from pamd.drivers.serial_line import LineField, SerialLineDriver, SerialLineOptions, check_line

from pamd.emulate.testing import wait_until
from pamd.wire.errors import DriverError


def nmea(body: str) -> str:
    x = 0
    for b in body.encode():
        x ^= b
    return f"${body}*{x:02X}"


def test_checksums() -> None:
    assert check_line(nmea("W,12.5"), "nmea") == ("W,12.5", "")
    assert check_line("$W,12.5*00", "nmea")[0] is None
    body = "ST,GS,+0012.50kg"
    s = sum(body.encode()) & 0xFF
    assert check_line(f"{body}{s:02X}", "sum8") == (body, "")
    assert check_line(f"{body}{(s + 1) & 0xFF:02X}", "sum8")[0] is None
    assert check_line("no checksum", "xor8")[0] is None


def test_options_are_checked() -> None:
    with pytest.raises(DriverError, match="no group"):
        SerialLineDriver("lc", SerialLineOptions(channels=(LineField(name="f", group="w"),)))
    with pytest.raises(DriverError, match="needs a request"):
        SerialLineDriver("lc", SerialLineOptions(mode="poll", channels=(LineField(name="f"),)))


@pytest.fixture
def made() -> Iterator[list[Any]]:
    out: list[Any] = []
    yield out
    for d in out:
        d.close()


def test_poll_mode_on_loop_url(made: list[Any]) -> None:
    d = SerialLineDriver("lc", SerialLineOptions(
        port="loop://", mode="poll", request=r"ST,GS,+0012.50kg\r\n", poll_period_s=0.005,
        pattern=r"(?P<status>ST|US),GS,(?P<w>[-+]\d+\.\d+)kg",
        channels=(LineField(name="force", group="w", scale=9.80665, unit="N"),)))
    made.append(d)
    d.open(time.monotonic)
    assert wait_until(lambda: d.in_values[0] == pytest.approx(12.5 * 9.80665))
    t = time.monotonic()
    assert wait_until(lambda: d.in_stamps_s[0] > t)
    assert d.health().ok and d.health().counters["requests"] > 0


class Pty:
    """The device end of a pty; the driver opens `path`."""

    def __init__(self) -> None:
        self.master, self.slave = os.openpty()
        self.path = os.ttyname(self.slave)

    def send(self, text: str) -> None:
        os.write(self.master, text.encode("latin-1"))

    def close(self) -> None:
        os.close(self.master)
        os.close(self.slave)


@pytest.fixture
def pty() -> Iterator[Pty]:
    p = Pty()
    yield p
    p.close()


def stream_driver(path: str, **kw: Any) -> SerialLineDriver:
    return SerialLineDriver("amp", SerialLineOptions(
        port=path, baud=115200, delimiter=",", checksum=kw.pop("checksum", "nmea"),
        timeout_s=kw.pop("timeout_s", 0.2), fault_after_s=0.1,
        channels=(LineField(name="force", field=1, unit="N"),
                  LineField(name="count", field=2)), **kw))


def test_stream_fields_checksum_and_garbage(pty: Pty, made: list[Any]) -> None:
    d = stream_driver(pty.path)
    made.append(d)
    d.open(time.monotonic)
    assert wait_until(lambda: d.connected)  # opening the port flushes its input
    pty.send(nmea("F,123.5,42") + "\r\n")
    assert wait_until(lambda: d.in_values[0] == 123.5 and d.in_values[1] == 42.0)
    pty.send("$F,124.0,43*00\r\n")  # bad checksum: not used
    pty.send(nmea("F,abc,44") + "\r\n")  # malformed field
    pty.send(nmea("F,1.0") + "\r\n")  # a field missing
    assert wait_until(lambda: d.health().counters.get("malformed_lines", 0) >= 2)
    h = d.health()
    assert h.counters["checksum_errors"] == 1 and h.counters["errors.force"] >= 1
    assert h.counters["errors.count"] >= 1
    assert any("channel force" in e and "'amp'" in e for e in h.errors)
    assert d.in_values[0] == 123.5  # nothing of a bad line was used
    pty.send("x" * 600)  # no line end at all
    assert wait_until(lambda: d.health().counters.get("overlong_lines", 0) >= 1)
    pty.send("\r\n" + nmea("F,125.0,45") + "\r\n")
    assert wait_until(lambda: d.in_values[0] == 125.0)
