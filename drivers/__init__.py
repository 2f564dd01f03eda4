"""The driver protocol and the registry that finds drivers by entry point.

A driver owns one device (or one simulated rig) and knows nothing about muscles.
It exposes numbered input and output channels. Its own thread does the bus I/O and
keeps `in_values` / `in_stamps_s` / `in_jitter_s` current; the loop only reads those lists and calls
`write()`, which must never block. A driver that cannot deliver sets `fault` to a
sentence naming the device; the supervisor turns that (or a stale stamp) into a
safe-state fault.

Drivers are registered in the `pamd.drivers` entry-point group:

    [project.entry-points."pamd.drivers"]
    mydevice = "mypackage.mydevice:MyDriver"
"""

from __future__ import annotations

import math
import os
from abc import ABC, abstractmethod
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from importlib.metadata import EntryPoint
from typing import Any, ClassVar, Literal, Protocol

from pamd.config.plugins import DRIVERS_GROUP, installed, load_driver_entry
from pamd.wire.errors import DriverError

Clock = Callable[[], float]
"""Returns the loop's time in seconds (monotonic, or virtual)."""


@dataclass(frozen=True)
class Channel:
    """One named input or output of a driver, in the driver's own (raw) unit.
    `digital`: the channel carries one bit (0 / 1: a solenoid valve's output, a
    Modbus coil), not a value on a scale."""

    name: str
    direction: Literal["in", "out"]
    unit: str = ""
    digital: bool = False


class SampleClock(Protocol):
    """A device's sample clock that paces the loop (`loop.clock: daq`): the loop waits
    for each sample instead of the OS timer. The device's thread publishes a sample's
    inputs, then waits for the loop's tick to store its outputs before it writes them.

    The loop's thread calls, in this order: `attach()` once before its first tick; per
    tick `wait(deadline_s)`, which returns the time of the sample clock's edge (on the
    loop's clock) that the newest sample was taken at, or NaN if none came by
    `deadline_s` (the OS clock stands in); `take_missed()`, the sample clocks that went
    by unticked since the last call (late samples the device reported and samples the
    loop was too late to take); `tick_done()` once the tick wrote its outputs; and
    `detach()` when it stops."""

    period_s: float

    def attach(self) -> None: ...

    def wait(self, deadline_s: float) -> float: ...

    def take_missed(self) -> int: ...

    def tick_done(self) -> None: ...

    def detach(self) -> None: ...

    def describe(self) -> str: ...


@dataclass
class DriverHealth:
    """What a driver reports about itself for status displays."""

    ok: bool
    fault: str | None = None
    counters: dict[str, int] = field(default_factory=dict)


@dataclass(frozen=True)
class NoOptions:
    """A driver without options."""


class Driver(ABC):
    """Base class of every driver. Subclasses set `options_type` to a dataclass that
    `pamd.config` validates (unknown keys, types, bounds) like the rest of the config."""

    options_type: ClassVar[type] = NoOptions
    steps_with_loop: ClassVar[bool] = False
    """True for simulated devices that the loop advances by one period per tick."""

    # The options are the driver's own dataclass (`options_type`, validated by pamd.config).
    # Any: each driver reads them as its own type (`o: ModbusOptions = self.options`)
    def __init__(self, name: str, options: Any) -> None:
        self.name = name
        self.options = options
        chans = list(self.channels())
        self.input_channels = [c for c in chans if c.direction == "in"]
        self.output_channels = [c for c in chans if c.direction == "out"]
        self.in_values: list[float] = [math.nan] * len(self.input_channels)
        self.in_stamps_s: list[float] = [-math.inf] * len(self.input_channels)
        # How far from its stamp each value may have been taken: 0 where the stamp is
        # the device's sample time; where the protocol gives none, the value is stamped
        # on arrival and this says how long it may have waited (a request's round trip;
        # a frame read from a backlog after the thread was held up), or where a sample
        # clock bounds it only from below, how much later. The plausibility checks
        # judge a change over the stamps' difference plus both values' jitter.
        self.in_jitter_s: list[float] = [0.0] * len(self.input_channels)
        self.preset_counts: list[int] = [0] * len(self.input_channels)
        self.fault: str | None = None

    @abstractmethod
    def channels(self) -> Sequence[Channel]:
        """All channels, known from the options alone (before `open`)."""

    @abstractmethod
    def open(self, clock: Clock) -> None:
        """Connect and start the I/O thread. Must not wait for the device to answer:
        a missing device sets `fault` and keeps retrying."""

    @abstractmethod
    def write(self, index: int, value: float) -> None:
        """Queue `value` for output channel `index`; never blocks."""

    @abstractmethod
    def close(self) -> None:
        """Stop the I/O thread and release the device."""

    def advance(self, dt_s: float) -> None:  # noqa: B027 - optional hook
        """Simulated devices only (`steps_with_loop`): advance physics by `dt_s`."""

    def is_absolute(self, index: int) -> bool:
        """True if input `index` is absolute, its own datum (an absolute encoder, a
        simulated rig), so it needs no `home`."""
        return False

    def preset_input(self, index: int, raw_value: float) -> bool:
        """Ask the device to read `raw_value` on input `index` from now on (an
        encoder's preset object, for `home`). Never blocks; returns False if the
        device cannot. `preset_counts[index]` grows once the device has applied it."""
        return False

    def change_load(self, input_index: int, load_kg: float) -> bool:
        """Simulated devices only: hang `load_kg` on the muscle that input `input_index`
        measures. Returns False where a person has to do it (real hardware)."""
        return False

    def set_safe_outputs(self, values: dict[int, float]) -> None:  # noqa: B027 - optional
        """Output index -> raw value the device should apply by itself if the host goes
        silent (a module's communication watchdog). Never blocks; no-op by default."""

    def claims(self) -> tuple[str, ...]:
        """What this driver opens that one process at a time may use, one name each
        (`serial_port_claim`, "Modbus TCP device HOST:PORT id N", "CAN channel
        INTERFACE:CHANNEL"): the daemon locks each before it opens anything
        (pamd.daemon.service.riglock). Simulated devices open nothing: () by default."""
        return ()

    def sample_clock(self) -> SampleClock | None:
        """The device's sample clock if it can pace the loop (`loop.clock: daq`), else
        None (the default: the loop runs on the OS timer)."""
        return None

    def health(self) -> DriverHealth:
        return DriverHealth(ok=self.fault is None, fault=self.fault)

    def input_index(self, channel: str) -> int:
        for i, c in enumerate(self.input_channels):
            if c.name == channel:
                return i
        raise KeyError(channel)

    def output_index(self, channel: str) -> int:
        for i, c in enumerate(self.output_channels):
            if c.name == channel:
                return i
        raise KeyError(channel)


def serial_port_claim(port: str) -> tuple[str, ...]:
    """The claim of a serial port or pyserial URL: the device itself (symlinks such as
    /dev/serial/by-id/... resolved, so two names of one port meet); none for
    `loop://`, which lives inside one process."""
    if not port or port.startswith("loop://"):
        return ()
    if "://" in port:
        return (f"serial port {port}",)
    return (f"serial port {os.path.realpath(port)}",)


def available_drivers() -> dict[str, EntryPoint]:
    """Driver type name -> entry point, for every installed driver."""
    return installed(DRIVERS_GROUP)


def load_driver_class(type_name: str) -> type[Driver]:
    """The driver class registered under `type_name`, or a DriverError listing the
    installed ones."""
    cls = load_driver_entry(type_name)
    if not (isinstance(cls, type) and issubclass(cls, Driver)):
        raise DriverError(f"entry point {type_name!r} does not name a pamd Driver class")
    return cls
