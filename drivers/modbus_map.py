"""Register maps of the `modbus` driver: the options schema, the value codec and
the read plan.

A channel (`ModbusPoint`) is one value on the device: a function (holding or
input register, coil, discrete input), an address, a data type with word order,
and a linear raw-to-volts scaling `volts = raw * scale + offset`. The rig's signal
calibration then takes volts on to SI units, so a map describes the module only.

`plan_reads` groups the input channels into as few read requests as the device
allows (contiguous addresses of the same function, at most 125 registers or 2000
bits per request); `encode`/`decode` convert between a channel value in its unit
(volts) and the registers on the wire.
"""

from __future__ import annotations

import math
import struct
from dataclasses import dataclass
from typing import Literal

from pamd.wire.schema.engine import spec

Function = Literal["holding", "input", "coil", "discrete"]
DataType = Literal["int16", "uint16", "int32", "uint32", "float32"]

REGISTER_FUNCTIONS = ("holding", "input")
BIT_FUNCTIONS = ("coil", "discrete")
MAX_READ_REGISTERS = 125  # Modbus limit for FC3/FC4
MAX_READ_BITS = 2000  # Modbus limit for FC1/FC2
MAX_WRITE_REGISTERS = 123  # Modbus limit for FC16

_WORDS = {"int16": 1, "uint16": 1, "int32": 2, "uint32": 2, "float32": 2}
_STRUCT = {"int16": ">h", "uint16": ">H", "int32": ">i", "uint32": ">I", "float32": ">f"}
_RANGE = {
    "int16": (-32768, 32767), "uint16": (0, 65535),
    "int32": (-2147483648, 2147483647), "uint32": (0, 4294967295),
    "float32": (-3.4e38, 3.4e38),
}


@dataclass(frozen=True, kw_only=True)
class ModbusPoint:
    """One channel of a Modbus device."""

    name: str = spec(doc="Channel name the rig's signals refer to (e.g. ai0, ao1, do0).")
    function: Function = spec("holding", "holding/input register, coil or discrete input. "
                              "Outputs are holding registers or coils.")
    address: int = spec(doc="Zero-based address on the wire (ADAM 40001 is 0).", min=0,
                        max=65535)
    type: DataType = spec("uint16", "Data type of a register channel (ignored for bits).")
    word_order: Literal["big", "little"] = spec(
        "big", "32-bit types: 'big' = high word at the lower address; 'little' swaps words.")
    scale: float = spec(1.0, "volts = raw * scale + offset (unit per count).")
    offset: float = spec(0.0, "Channel value at raw 0, in the channel's unit.")
    unit: str = spec("V", "Unit of the scaled value (what the rig's signal gain starts from).")
    raw_min: float | None = spec(None, "Outputs: lowest raw value ever sent (default: the "
                                 "type's range).")
    raw_max: float | None = spec(None, "Outputs: highest raw value ever sent (e.g. 4095 for a "
                                 "12-bit DAC).")
    safe_address: int | None = spec(
        None, "Outputs: address (same function) where the module keeps this output's "
        "communication-safety value (applied by the module when the host goes silent). "
        "null: the module has none or it is set with the vendor's tool.", min=0, max=65535)

    @property
    def words(self) -> int:
        return 1 if self.function in BIT_FUNCTIONS else _WORDS[self.type]

    @property
    def is_bit(self) -> bool:
        return self.function in BIT_FUNCTIONS


@dataclass(frozen=True, kw_only=True)
class CommSafety:
    """The module's communication watchdog (ADAM 'Comm Safety' / WAGO fieldbus watchdog)."""

    timeout_address: int | None = spec(
        None, "Holding register that sets the watchdog time (null: set on the module).",
        min=0, max=65535)
    timeout_s: float = spec(0.5, "Watchdog time: outputs go to their safe values after the "
                            "host has been silent this long.", unit="s", gt=0.0)
    timeout_unit_s: float = spec(0.1, "Time per count of the timeout register.", unit="s",
                                 gt=0.0)


@dataclass(frozen=True, kw_only=True)
class SampleClock:
    """A register that says when the module sampled its inputs, where it has one: a
    counter that steps with every new sample, or the age of the present sample. The
    inputs are then stamped with their sample's time, not the time they were read, so
    a module that samples slower than it is polled (an ADAM-6024 takes 10 samples/s)
    never looks fresher than it is, and one whose sampling stops goes stale."""

    function: Literal["holding", "input"] = spec("input", "Register type.")
    address: int = spec(doc="Zero-based address of the register.", min=0, max=65535)
    holds: Literal["counter", "age"] = spec(
        "counter", "What the register holds. counter: steps by one (mod 65536) with each "
        "new sample; the values are stamped with the read before the counter was seen to "
        "step (never later than the sample). age: the sample's age in `unit_s` counts at "
        "the time of the read.",
        old="kind")
    unit_s: float = spec(0.001, "age: seconds per count.", unit="s", gt=0.0)


class SampleTimes:
    """The sample time a `SampleClock` register gives the values read with (or after)
    it: `sample_s` and its `jitter_s`. Counter: a step since its last read means a
    sample taken after that read (its time: the conservative stamp; it may be as late
    as this read); no step, the same sample as before. Age: the age in its unit, read
    within the round trip."""

    def __init__(self, clock: SampleClock) -> None:
        self._clock = clock
        self._counter: int | None = None  # the sample counter as last read
        self._counter_read_s = -math.inf  # when it was last read
        self.sample_s = -math.inf  # stamp of the present sample
        self.jitter_s = 0.0

    def read(self, word: int, now: float, round_trip_s: float) -> None:
        """The register read `word` at `now`, within `round_trip_s`."""
        sc = self._clock
        if sc.holds == "age":
            self.sample_s = now - word * sc.unit_s
            self.jitter_s = sc.unit_s + round_trip_s
        elif self._counter is None:
            self.sample_s = now  # the first read: stamped as read (no earlier bound)
            self.jitter_s = round_trip_s
        elif word != self._counter:
            self.sample_s = self._counter_read_s
            self.jitter_s = now - self._counter_read_s
        self._counter, self._counter_read_s = word, now


def type_range(point: ModbusPoint) -> tuple[float, float]:
    """Lowest and highest raw value the point can carry, tightened by raw_min/raw_max."""
    if point.is_bit:
        lo, hi = 0.0, 1.0
    else:
        lo, hi = _RANGE[point.type]
    if point.raw_min is not None:
        lo = max(lo, point.raw_min)
    if point.raw_max is not None:
        hi = min(hi, point.raw_max)
    return float(lo), float(hi)


def decode(point: ModbusPoint, words: list[int]) -> float:
    """Registers (already sliced to `point.words`) -> raw number."""
    if len(words) == 1:
        w = words[0] & 0xFFFF
        return float(w - 0x10000 if point.type == "int16" and w & 0x8000 else w)
    hi, lo = (words[0], words[1]) if point.word_order == "big" else (words[1], words[0])
    raw = struct.unpack(_STRUCT[point.type], struct.pack(">HH", hi & 0xFFFF, lo & 0xFFFF))[0]
    return float(raw)


def to_value(point: ModbusPoint, raw: float) -> float:
    """Raw number -> channel value (volts)."""
    return raw * point.scale + point.offset


def to_raw(point: ModbusPoint, value: float) -> float:
    """Channel value (volts) -> raw number, rounded for integers and clamped to range."""
    raw = (value - point.offset) / point.scale
    lo, hi = type_range(point)
    if point.is_bit:
        return 1.0 if raw >= 0.5 else 0.0
    if point.type != "float32":
        raw = float(math.floor(raw + 0.5))
    return lo if raw < lo else (hi if raw > hi else raw)


def encode(point: ModbusPoint, raw: float) -> list[int]:
    """Raw number (from `to_raw`) -> registers on the wire."""
    if point.is_bit:
        return [1 if raw >= 0.5 else 0]
    if point.type == "float32":
        data = struct.pack(">f", raw)
    else:
        data = struct.pack(_STRUCT[point.type], int(raw))
    words = list(struct.unpack(f">{len(data) // 2}H", data))
    if len(words) == 2 and point.word_order == "little":
        words.reverse()
    return words


@dataclass(frozen=True)
class Block:
    """One read (or write) request: contiguous addresses of one function."""

    function: str
    start: int
    count: int
    members: tuple[tuple[int, int], ...]  # (channel index, offset in the block)
    names: tuple[str, ...]

    @property
    def label(self) -> str:
        registers = {"holding": "holding registers", "input": "input registers",
                "coil": "coils", "discrete": "discrete inputs"}[self.function]
        end = self.start + self.count - 1
        where = f"{self.start}" if end == self.start else f"{self.start}-{end}"
        return f"{registers} {where} ({', '.join(self.names)})"


def plan_blocks(points: tuple[ModbusPoint, ...], max_gap: int = 0,
                max_registers: int = MAX_READ_REGISTERS) -> list[Block]:
    """Group points into requests: same function, addresses at most `max_gap` apart,
    at most `max_registers` registers (2000 bits) per request."""
    order = sorted(range(len(points)), key=lambda i: (points[i].function, points[i].address))
    blocks: list[Block] = []
    cur: list[int] = []

    def flush() -> None:
        if not cur:
            return
        p0 = points[cur[0]]
        start = p0.address
        end = max(points[i].address + points[i].words for i in cur)
        blocks.append(Block(p0.function, start, end - start,
                            tuple((i, points[i].address - start) for i in cur),
                            tuple(points[i].name for i in cur)))
        cur.clear()

    for i in order:
        p = points[i]
        if cur:
            p0 = points[cur[0]]
            end = max(points[j].address + points[j].words for j in cur)
            limit = MAX_READ_BITS if p.is_bit else max_registers
            if (p.function != p0.function or p.address > end + max_gap
                    or p.address + p.words - p0.address > limit):
                flush()
        cur.append(i)
    flush()
    return blocks


def check_points(points: tuple[ModbusPoint, ...], outputs: bool) -> list[str]:
    """Problems the per-field bounds cannot catch (names, overlaps, output functions)."""
    problems = []
    seen: dict[str, int] = {}
    for p in points:
        if p.name in seen:
            problems.append(f"channel name {p.name!r} is used twice")
        seen[p.name] = 1
        if p.scale == 0.0:
            problems.append(f"channel {p.name!r}: scale must not be 0")
        if p.address + p.words - 1 > 65535:
            problems.append(f"channel {p.name!r}: address {p.address} + {p.words} words runs "
                            "past 65535")
        if outputs and p.function not in ("holding", "coil"):
            problems.append(f"output {p.name!r}: function must be holding or coil, not "
                            f"{p.function}")
        if not outputs and p.safe_address is not None:
            problems.append(f"input {p.name!r}: safe_address only applies to outputs")
    used: dict[tuple[str, int], str] = {}
    for p in points:
        for a in range(p.address, p.address + p.words):
            key = (p.function, a)
            if key in used and used[key] != p.name:
                problems.append(f"channels {used[key]!r} and {p.name!r} overlap at "
                                f"{p.function} address {a}")
            used[key] = p.name
    return problems
