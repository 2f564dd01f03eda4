"""The actuation stage of one muscle's tick: how its command reaches its valves.

An `Actuation` takes the command the limiter let through (a pressure, bar) once per
tick and drives the muscle's outputs with it. Today's one is `RegulatorActuation`:
a proportional pressure regulator's setpoint plus the optional exhaust valve,
opened only when the tick asks to vent (a safe state whose safe pressure is 0).

Made to fit on/off valves too (issue #14): an inflate and an exhaust digital
output switched by PWM or a sliding mode (`pamd.control.onoff`) would implement the
same Protocol, using the measured pressure and the tick's time in `write`, counting
its valve switches in `switch_count`, and saying what its outputs hold in the safe
state (`safe_outputs`: both closed holds the air in; the exhaust open vents).

How to add an actuation: a class with these members in `pamd/control/`, built by
`actuation_for` from the muscle's signals; nothing else in the tick changes.
`write` is on the tick path: float arithmetic and the drivers' non-blocking
`write`, nothing allocated.
"""

from __future__ import annotations

from typing import NamedTuple, Protocol

from pamd.rig import MuscleSignals, OutputBinding
from pamd.tick import Flag

F_EXHAUST = int(Flag.EXHAUST_OPEN)


class SafeOutput(NamedTuple):
    """What one output holds in the safe state, in SI (for devices that fall back to
    preset outputs by themselves: `pamd.drivers.safe_outputs`)."""

    binding: OutputBinding
    value: float
    unit: str  # "bar", or "(1 = open)" for a valve


class Actuation(Protocol):
    """How one muscle's command reaches its valves."""

    exhaust_open: bool  # the exhaust valve is open (vented)
    switch_count: int  # valve switches since start (the record and the summary)

    def write(self, command_bar: float, pressure_bar: float, now_s: float, dt_s: float,
              vent: bool) -> int:
        """Drive the outputs for this tick: `command_bar` is the limited command,
        `pressure_bar` the measured pressure, `vent` whether the tick asks to vent (the
        safe pressure is 0 and the command reached it). Returns the tick record's flag
        bits it sets (EXHAUST_OPEN). Tick path: never blocks, allocates nothing."""
        ...

    def safe_outputs(self, safe_pressure_bar: float) -> list[SafeOutput]:
        """What each output holds in the safe state with this safe pressure."""
        ...


class RegulatorActuation:
    """A proportional pressure regulator's setpoint, plus the optional exhaust valve."""

    def __init__(self, valve: OutputBinding, exhaust: OutputBinding | None) -> None:
        self.valve = valve
        self.exhaust = exhaust
        self.exhaust_open = False
        self.switch_count = 0

    def write(self, command_bar: float, pressure_bar: float, now_s: float, dt_s: float,
              vent: bool) -> int:
        self.valve.write_si(command_bar)
        exhaust = self.exhaust
        if exhaust is None:
            return 0
        if vent != self.exhaust_open:
            exhaust.write_si(1.0 if vent else 0.0)
            self.exhaust_open = vent
            self.switch_count += 1
        return F_EXHAUST if vent else 0

    def safe_outputs(self, safe_pressure_bar: float) -> list[SafeOutput]:
        out = [SafeOutput(self.valve, safe_pressure_bar, "bar")]
        if self.exhaust is not None:
            out.append(SafeOutput(self.exhaust, 1.0 if safe_pressure_bar == 0.0 else 0.0,
                                  "(1 = open)"))
        return out


def actuation_for(signals: MuscleSignals) -> Actuation:
    """The actuation a muscle's signals describe (today: a regulator and an exhaust)."""
    return RegulatorActuation(signals.valve, signals.exhaust)
