"""A timed pulse of one on/off valve: the step test of `pamd tune --loop onoff`, as a
tick-side element of `OnOffActuation`.

Armed by the `pulse` command (`pamd.loop.commands.tune_verbs`), which checked it against the
muscle's limits first. While active it holds the valves instead of the PWM: both
shut for `rest_s`, the one valve open for `pulse_s`, both shut for `after_s`; then
it is done (the PWM takes the valves again). In loop time, tick by tick: on the
virtual clock the same every run.

It ends early, the valve shut at once, with the reason as its outcome, when:
- the command moves (a setpoint, a stop, a safe state's ramp): the pressure before
  and after the pulse would not be the valve's doing;
- a safe state, a vent or mode position takes the valves;
- the pressure is not trusted (or the air is cut: nothing to measure);
- an inflate pulse reaches `high_bar` or an exhaust pulse `low_bar` (the pressure
  limit and the safe pressure the command gave): the command's check predicted the
  pulse from the config's rates, this one watches the pressure itself.

Tick path: float arithmetic only, the outcomes are constant strings.
"""

from __future__ import annotations

from pamd.loop.control.onoff import EXHAUST, HOLD, INFLATE
from pamd.loop.control.relay import DONE, TickTest

MOVED = "the command moved (a setpoint, a stop or a safe state's ramp)"
TAKEN = "a safe state, a vent or mode position took the valves"
UNTRUSTED = "the pressure is not trusted (or the air is cut)"
AT_LIMIT = "the pressure reached the pressure limit: the inflate valve shut"
AT_SAFE = "the pressure reached the safe pressure: the exhaust valve shut"


class ValvePulse(TickTest):
    """One timed valve pulse; inactive until `start`. `stop` shuts both valves this
    tick (the PWM takes them again)."""

    def __init__(self) -> None:
        super().__init__()
        self.valve = HOLD
        self.pulse_s = self.rest_s = self.after_s = 0.0
        self.low_bar = self.high_bar = 0.0
        self.elapsed_s = 0.0
        self.command_bar = float("nan")

    def start(self, valve: int, pulse_s: float, rest_s: float, after_s: float,
              low_bar: float, high_bar: float) -> None:
        """Arm the pulse (the caller checked it); the next tick begins it."""
        self.valve = valve
        self.pulse_s, self.rest_s, self.after_s = pulse_s, rest_s, after_s
        self.low_bar, self.high_bar = low_bar, high_bar
        self.elapsed_s = 0.0
        self.command_bar = float("nan")
        self.begin()

    def step(self, command_bar: float, pressure_bar: float, dt_s: float) -> int:
        """The valves' state this tick (INFLATE, EXHAUST or HOLD) while active."""
        c = self.command_bar
        if c != c:
            self.command_bar = command_bar  # the command the pulse holds on to
        elif command_bar != c:
            self.stop(MOVED)
            return HOLD
        if pressure_bar != pressure_bar:
            self.stop(UNTRUSTED)
            return HOLD
        t = self.elapsed_s + dt_s
        self.elapsed_s = t
        t -= 0.5 * dt_s  # the tick's middle: whole ticks per phase, no float drift
        if t <= self.rest_s:
            return HOLD
        if t <= self.rest_s + self.pulse_s:
            valve = self.valve
            if valve == INFLATE and pressure_bar >= self.high_bar:
                self.stop(AT_LIMIT)
                return HOLD
            if valve == EXHAUST and pressure_bar <= self.low_bar:
                self.stop(AT_SAFE)
                return HOLD
            return valve
        if t > self.rest_s + self.pulse_s + self.after_s:
            self.stop(DONE)
        return HOLD
