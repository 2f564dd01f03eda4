"""The `serial-line` driver: line-oriented ASCII devices on a serial port
(load-cell amplifiers, counters).

Either the device streams lines by itself (`mode: stream`) or the driver sends
`request` and waits for one answer line (`mode: poll`). Each line is checked
(optional checksum), then every channel takes its number from a regex group or
from a delimited field, scaled `value = number * scale + offset`, and is stamped
with the loop's clock when the line arrived and a jitter, how much earlier the
device may have measured it (poll: since the request went out; stream: since the
thread last found the port idle, `ArrivalWindow`). A line that fails any of this is
counted and logged with the device and channel named, and none of its values is
used. Silence, a vanished port and persistent garbage set `fault` after
`fault_after_s`; the port is re-opened with backoff. Load-cell transmitters that
speak Modbus RTU use the `modbus` driver instead.
"""

from __future__ import annotations

import codecs
import contextlib
import math
import re
import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Literal

from pamd.drivers import Channel, serial_port_claim
from pamd.drivers.device import ArrivalWindow, Backoff, ThreadedDriver

from pamd.wire.errors import DriverError
from pamd.wire.schema.engine import spec


@dataclass(frozen=True, kw_only=True)
class LineField:
    """One value taken from each line."""

    name: str = spec(doc="Channel name.")
    group: str = spec("1", "Regex group (name or number) holding the number.")
    field: int | None = spec(None, "Instead of a regex group: this field (from 0) of the line "
                             "split at `delimiter`.", min=0)
    scale: float = spec(1.0, "value = number * scale + offset.")
    offset: float = spec(0.0, "Value at number 0.")
    unit: str = spec("", "Unit of the scaled value.")


@dataclass(frozen=True, kw_only=True)
class SerialLineOptions:
    """Options of the `serial-line` driver."""

    port: str = spec("/dev/ttyUSB0", "Serial device or pyserial URL (loop://, a pty).")
    baud: int = spec(9600, "Baud rate.", unit="baud", min=50, max=4000000)
    bytesize: int = spec(8, "Data bits.", min=5, max=8)
    parity: Literal["N", "E", "O", "M", "S"] = spec("N", "Parity.")
    stopbits: int = spec(1, "Stop bits.", min=1, max=2)
    mode: Literal["stream", "poll"] = spec("stream", "The device sends lines by itself, or "
                                           "answers `request`.")
    request: str = spec("", "Poll mode: sent each poll (escapes like \\r allowed).")
    poll_period_s: float = spec(0.01, "Poll mode: send a request this often.", unit="s",
                                min=0.0)
    terminator: str = spec("\\n", "End of a line (escapes allowed); a trailing \\r is "
                           "dropped too.")
    encoding: str = spec("ascii", "Text encoding of the lines.")
    pattern: str = spec(r"([-+]?\d+(?:\.\d*)?(?:[eE][-+]?\d+)?)",
                        "Regex searched in each line; channels take its groups.")
    delimiter: str | None = spec(None, "Field mode: split lines here (null: whitespace).")
    checksum: Literal["none", "nmea", "sum8", "xor8"] = spec(
        "none", "nmea: '$payload*HH' XOR; sum8/xor8: the line ends in two hex digits of the "
        "byte sum / XOR of everything before them.")
    timeout_s: float = spec(0.1, "Poll mode: wait this long for the answer; stream mode: "
                            "silent after this long without a line.", unit="s", gt=0.0)
    max_line_bytes: int = spec(256, "Longer lines are discarded as garbage.", min=8,
                               max=65536)
    fault_after_s: float = spec(0.3, "Failure lasting this long sets the driver's fault.",
                                unit="s", gt=0.0)
    reconnect_min_s: float = spec(0.05, "First reopen delay.", unit="s", gt=0.0)
    reconnect_max_s: float = spec(2.0, "Longest reopen delay.", unit="s", gt=0.0)
    channels: tuple[LineField, ...] = spec(doc="The values in each line.")


def _unescape(text: str) -> str:
    return codecs.decode(text, "unicode_escape")


def check_line(line: str, checksum: str) -> tuple[str | None, str]:
    """(payload, why): the line without its checksum, or None and the reason."""
    if checksum == "none":
        return line, ""
    if checksum == "nmea":
        m = re.fullmatch(r"\$?([^*]*)\*([0-9A-Fa-f]{2})", line)
        if m is None:
            return None, "no '*HH' checksum"
        body, want = m.group(1), int(m.group(2), 16)
        got = 0
        for b in body.encode("latin-1", "replace"):
            got ^= b
        return (body, "") if got == want else (None, f"checksum {got:02X} != {want:02X}")
    if len(line) < 3 or not re.fullmatch(r"[0-9A-Fa-f]{2}", line[-2:]):
        return None, "no trailing hex checksum"
    body, want = line[:-2], int(line[-2:], 16)
    data = body.encode("latin-1", "replace")
    got = sum(data) & 0xFF
    if checksum == "xor8":
        got = 0
        for b in data:
            got ^= b
    return (body, "") if got == want else (None, f"checksum {got:02X} != {want:02X}")


class SerialLineDriver(ThreadedDriver):
    """ASCII line devices: stream or request/response."""

    options_type = SerialLineOptions

    def __init__(self, name: str, options: SerialLineOptions | None = None) -> None:
        o = options if options is not None else SerialLineOptions(channels=(
            LineField(name="value"),))
        try:
            self.regex = re.compile(o.pattern)
        except re.error as exc:
            raise DriverError(f"serial-line driver {name!r}: bad pattern: {exc}") from None
        names = [c.name for c in o.channels]
        if not names or len(set(names)) != len(names):
            raise DriverError(f"serial-line driver {name!r}: needs channels with unique names")
        for c in o.channels:
            if c.field is None and not (c.group.isdigit() and int(c.group) <= self.regex.groups
                                        or c.group in self.regex.groupindex):
                raise DriverError(f"serial-line driver {name!r}: channel {c.name!r}: the "
                                  f"pattern has no group {c.group!r}")
        if o.mode == "poll" and not o.request:
            raise DriverError(f"serial-line driver {name!r}: poll mode needs a request")
        super().__init__(name, o)
        self.fault_after_s = o.fault_after_s
        self.term = _unescape(o.terminator).encode(o.encoding)
        self.request_bytes = _unescape(o.request).encode(o.encoding)
        self._port: Any = None  # Any: a pyserial Serial (untyped third party), opened in run
        self._buf = bytearray()
        self._last_line = time.monotonic()
        self._window = ArrivalWindow()
        self._sent_at = -math.inf  # the loop's clock when the last request went out
        self.last_problem: str | None = None

    def channels(self) -> Sequence[Channel]:
        return [Channel(c.name, "in", c.unit) for c in self.options.channels]

    def write(self, index: int, value: float) -> None:
        raise DriverError(f"{self.describe()} has no outputs")

    def claims(self) -> tuple[str, ...]:
        return serial_port_claim(self.options.port)

    def describe(self) -> str:
        o: SerialLineOptions = self.options
        return f"serial-line {self.name!r} ({o.port} {o.baud} {o.bytesize}{o.parity}{o.stopbits})"

    # -- the I/O thread -----------------------------------------------------------------
    def _open(self) -> bool:
        import serial

        o: SerialLineOptions = self.options
        try:
            self._port = serial.serial_for_url(o.port, baudrate=o.baud, bytesize=o.bytesize,
                                               parity=o.parity, stopbits=o.stopbits,
                                               timeout=0.005)
        except Exception as exc:  # noqa: BLE001 - missing port, busy, bad URL: retry
            self.error("open_failures", f"cannot open the port: {exc}")
            return False
        self._buf.clear()
        self._last_line = time.monotonic()
        self.connected = True
        self.count("opens")
        return True

    def release(self) -> None:
        port, self._port = self._port, None
        self.connected = False
        if port is not None:
            with contextlib.suppress(Exception):
                port.close()

    def run(self) -> None:
        o: SerialLineOptions = self.options
        backoff = Backoff(o.reconnect_min_s, o.reconnect_max_s)
        mono = time.monotonic
        next_poll = mono()
        while not self.stopping.is_set():
            if self._port is None:
                if not self._open():
                    self.failing(f"cannot open the port ({self.recent_errors[-1]})")
                    self.stopping.wait(backoff.next())
                    continue
                backoff.reset()
            try:
                if o.mode == "poll":
                    self._poll_once()
                    next_poll += o.poll_period_s
                    rest = next_poll - mono()
                    if rest > 0:
                        self.stopping.wait(rest)
                    else:
                        next_poll = mono()
                else:
                    self._read_lines()
                    if mono() - self._last_line > o.timeout_s:
                        self.last_problem = (f"silent: no line for "
                                             f"{1000 * (mono() - self._last_line):.0f} ms")
            except Exception as exc:  # noqa: BLE001 - the port vanished or broke
                self.error("port_errors", f"port error: {exc}")
                self.release()
                self.failing(f"port error: {exc}")
                self.stopping.wait(backoff.next())
                continue
            if self.last_problem is None:
                self.healthy()
            else:
                self.failing(self.last_problem)
        self.release()

    def _poll_once(self) -> None:
        o: SerialLineOptions = self.options
        port = self._port
        port.reset_input_buffer()
        self._buf.clear()
        self._sent_at = self.clock()
        port.write(self.request_bytes)
        self.count("requests")
        deadline = time.monotonic() + o.timeout_s
        got = 0
        while got == 0 and time.monotonic() < deadline and not self.stopping.is_set():
            got = self._read_lines()
        if got == 0:
            self.last_problem = self.error(
                "timeouts", f"no answer to {o.request!r} within {1000 * o.timeout_s:.0f} ms",
                tuple(c.name for c in o.channels))

    def _read_lines(self) -> int:
        """Read what is there; parse every complete line. Returns lines parsed."""
        port = self._port
        self._window.before_read(self.clock())
        chunk = port.read(max(1, port.in_waiting))
        self._window.after_read(self.clock(), bool(chunk))
        if chunk:
            self._buf += chunk
        n = 0
        while True:
            k = self._buf.find(self.term)
            if k < 0:
                if len(self._buf) > self.options.max_line_bytes:
                    self.last_problem = self.error(
                        "overlong_lines", f"{len(self._buf)} bytes without a line end")
                    self._buf.clear()
                return n
            raw = bytes(self._buf[:k])
            del self._buf[:k + len(self.term)]
            self._parse(raw)
            n += 1

    def _parse(self, raw: bytes) -> None:
        o: SerialLineOptions = self.options
        now_mono = time.monotonic()
        self._last_line = now_mono
        names = tuple(c.name for c in o.channels)
        text = raw.decode(o.encoding, "replace").strip("\r\n")
        if not text.strip():
            self.count("empty_lines")
            return
        body, why = check_line(text.strip(), o.checksum)
        if body is None:
            self.last_problem = self.error("checksum_errors", f"line {text!r}: {why}", names)
            return
        m = self.regex.search(body)
        fields = body.split(o.delimiter) if o.delimiter is not None else body.split()
        values = []
        for c in o.channels:
            try:
                if c.field is not None:
                    token = fields[c.field].strip()
                else:
                    if m is None:
                        raise ValueError("pattern not found")
                    token = m.group(int(c.group) if c.group.isdigit() else c.group)
                values.append(float(token) * c.scale + c.offset)
            except (ValueError, IndexError, TypeError) as exc:
                self.last_problem = self.error("malformed_lines",
                                               f"line {text!r}: channel {c.name}: {exc}",
                                               (c.name,))
                return
        now = self.clock()
        jitter = (now - self._sent_at if o.mode == "poll" else self._window.jitter_s(now))
        for i, v in enumerate(values):
            if v != v or v in (float("inf"), float("-inf")):
                self.last_problem = self.error("malformed_lines",
                                               f"line {text!r}: channel {names[i]}: not finite",
                                               (names[i],))
                return
        for i, v in enumerate(values):
            self.stamp(i, v, now, jitter)
        self.count("lines")
        self.last_problem = None
