"""The rig: drivers built from the config, and each muscle's named signals bound to
driver channels with calibration (raw -> SI) and datums (home, tare).

Drivers know nothing of muscles; the rig knows nothing of protocols.
"""

from __future__ import annotations

import contextlib
import math
from dataclasses import dataclass

from pamd.config.loader import LoadedConfig, effective_timeout_s
from pamd.config.safety_schema import SafetyConfig
from pamd.config.schema import SignalConfig
from pamd.drivers import Clock, Driver, load_driver_class
from pamd.loop.devices.datum_file import Calibration, MuscleDatums
from pamd.wire.errors import ConfigError, ConfigIssue, DriverError


@dataclass
class InputBinding:
    """One input signal: where it comes from and how raw becomes SI."""

    name: str  # e.g. "m1.pressure"
    driver: Driver
    index: int
    gain: float
    offset: float
    timeout_s: float

    @property
    def values(self) -> list[float]:
        return self.driver.in_values

    @property
    def stamps(self) -> list[float]:
        return self.driver.in_stamps_s

    def read_si(self) -> tuple[float, float]:
        """(SI value, stamp) - not for the tick path."""
        return (self.gain * self.driver.in_values[self.index] + self.offset,
                self.driver.in_stamps_s[self.index])


@dataclass
class OutputBinding:
    """One output signal: SI -> raw, clamped to the configured raw range."""

    name: str
    driver: Driver
    index: int
    gain: float
    offset: float
    raw_min: float
    raw_max: float

    def write_si(self, value: float) -> float:
        raw = (value - self.offset) / self.gain
        raw = self.raw_min if raw < self.raw_min else (self.raw_max if raw > self.raw_max else raw)
        self.driver.write(self.index, raw)
        return raw


@dataclass
class MuscleSignals:
    pressure: InputBinding
    force: InputBinding
    length: InputBinding
    valve: OutputBinding | None  # the regulator (actuation: proportional)
    exhaust: OutputBinding | None  # the exhaust valve (beside a regulator, or on/off's)
    datums: MuscleDatums
    inflate: OutputBinding | None = None  # on/off's inflate valve (actuation: onoff)


class Rig:
    """Drivers and signal bindings for a validated config."""

    def __init__(self, cfg: LoadedConfig, calibration: Calibration) -> None:
        self.cfg = cfg
        self.calibration = calibration
        self.drivers: dict[str, Driver] = {}
        for d in cfg.rig.drivers:
            cls = load_driver_class(d.type)
            self.drivers[d.name] = cls(d.name, d.options)
        self.steppers = [d for d in self.drivers.values() if d.steps_with_loop]
        safety = cfg.rig.safety
        self.muscles: list[MuscleSignals] = []
        for m in cfg.rig.muscles:
            s = m.signals
            datums = calibration.for_muscle(m.name)
            length = self._input(f"{m.name}.length", s.length, safety)
            self.absolute_length = (length.driver.is_absolute(length.index)
                                    or s.length.absolute)
            if self.absolute_length:  # an absolute sensor has its datum by construction
                datums.has_length_datum = True
            self.muscles.append(MuscleSignals(
                pressure=self._input(f"{m.name}.pressure", s.pressure, safety),
                force=self._input(f"{m.name}.force", s.force, safety),
                length=length,
                valve=(None if m.actuation == "onoff" else
                       self._output(f"{m.name}.valve", _required(s.valve, cfg.path, m.name))),
                exhaust=self._output(f"{m.name}.exhaust", s.exhaust) if s.exhaust else None,
                datums=datums,
                inflate=(self._output(f"{m.name}.inflate", s.inflate)
                         if m.actuation == "onoff" and s.inflate else None),
            ))

    def _input(self, name: str, sig: SignalConfig, safety: SafetyConfig) -> InputBinding:
        """The binding's timeout is the age at which the value is stale, counted from
        its stamp (the sample's time where the driver knows it): see
        `effective_timeout_s`."""
        drv = self.drivers[sig.driver]
        return InputBinding(name, drv, drv.input_index(sig.channel), sig.gain, sig.offset,
                            effective_timeout_s(sig, safety))

    def _output(self, name: str, sig: SignalConfig) -> OutputBinding:
        drv = self.drivers[sig.driver]
        lo = -math.inf if sig.raw_min is None else sig.raw_min
        hi = math.inf if sig.raw_max is None else sig.raw_max
        return OutputBinding(name, drv, drv.output_index(sig.channel), sig.gain, sig.offset,
                             lo, hi)

    def open(self, clock: Clock) -> None:
        """Open every driver. A driver that raises here is reported with its name;
        drivers are expected to keep retrying a missing device rather than raise."""
        opened: list[Driver] = []
        for name, drv in self.drivers.items():
            try:
                drv.open(clock)
            except Exception as exc:  # a driver's own failure, reported with its name
                for o in opened:
                    o.close()
                raise DriverError(f"driver {name!r} ({type(drv).__name__}) failed to open: "
                                  f"{exc}") from exc
            opened.append(drv)

    def close(self) -> None:
        for drv in self.drivers.values():
            with contextlib.suppress(Exception):  # closing must go on for the others
                drv.close()

    def driver(self, name: str) -> Driver:
        return self.drivers[name]


def _required(sig: SignalConfig | None, path: str, muscle: str) -> SignalConfig:
    """The regulator setpoint that `actuation: proportional` requires (the loader
    refuses a config without it: pamd.config.actuation_rules)."""
    if sig is None:
        raise ConfigError([ConfigIssue(path, None, f"muscles ({muscle}).signals.valve",
                                       "the pressure regulator's setpoint output", "none")])
    return sig
