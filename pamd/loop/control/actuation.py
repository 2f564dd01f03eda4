"""The actuation stage of one muscle's tick: how its command reaches its valves.

An `Actuation` is the last stage of the muscle's write (`update(t, now_s, dt_s)` on
the muscle's `pamd.wire.tick.MuscleTick`, as every stage): it takes the command the
limiter let through (a pressure, bar) once per tick and drives the muscle's outputs
with it; `actuation_for` picks it from the muscle's `actuation`. What an actuation
does beyond following the command it says by two attributes the muscle reads when
it is built and when its mode changes, never per tick: `closes_pressure_loop` (its
own law closes the pressure loop, the muscle's PID adds nothing) and
`positions_length` (in mode position it positions the length itself, on the targets
the muscle hands it through its `MuscleTick`).

`RegulatorActuation` (`actuation: proportional`): a proportional pressure
regulator's setpoint plus the optional exhaust valve, opened only when the tick asks
to vent (a safe state whose safe pressure is 0).

`OnOffActuation` (`actuation: onoff`, seed 004's rig): the command reaches an
inflate and an exhaust solenoid valve by PWM. The limiter still decides the
command; this stage only makes the valves deliver it. For an on/off muscle the
tick's PID adds nothing (`closes_pressure_loop`: `MuscleController` zeroes its
gains): the pressure loop is here, where the valves' rates are known.

The law, each tick: the rate of pressure wanted is

    want = (e + integral) / response_s + command rate        (bar/s, e = command - p)

and the duty is `want / fill_rate` (inflate) or `want / vent_rate` (exhaust): the
rates a step test on the rig measures (pamd tune --loop onoff), never the simulator's
parameters. `Pulser` turns the duty into a pulse at the start of each PWM period; a
pulse the valves cannot pass (shorter than twice the opening delay) is not sent.

At rest (a steady command within `dead_band_bar` of the pressure, low-passed over
a PWM period; left again beyond twice the band) both valves hold and the integral
stays: no chatter on the sensor's noise. Venting (the safe state at a safe pressure of 0,
a vent ESTOP) opens the exhaust and closes the inflate valve.

In mode position an on/off muscle follows seed 004's sliding mode instead
(`SlidingModePosition`: a sliding surface on the length error and its rate, a
boundary layer, inflate / hold / exhaust; `positions_length`, the muscle's
`position_valves`), filling never above the limiter's ceiling (`ceiling_bar`); a safe
state leaves the length mode, so PWM takes the safe ramp.

In a safe state (`valve_floor_bar`, every tick the muscle is in one) the exhaust never
opens at or below the safe pressure plus what drains while it closes (the vent rate
times its closing delay, plus the dead band), and the integral never holds the
pressure below it: on/off valves do not hold a pressure by themselves, so without
this floor the PI's wound-up integral vented a loaded muscle 0.35 bar under its
safe pressure for a second after a fault (issue 23).

`pamd tune --loop onoff` times single valve pulses through it (`pulse`, a
`ValvePulse`): while one is active it holds the valves instead of the PWM.

Each valve's switchings are counted (`inflate_switches`, `exhaust_switches`):
valve wear is what on/off users watch. Tick path: float arithmetic and the drivers'
non-blocking `write`, only on a change.

How to add an actuation: a class with these members in `pamd/loop/control/`, built by
`actuation_for` from the muscle's signals; nothing else in the tick changes.
`update` is on the tick path: float arithmetic and the drivers' non-blocking
`write`, nothing allocated.
"""

from __future__ import annotations

import math
from typing import NamedTuple, Protocol

from pamd.config.schema import MuscleConfig, OnOffConfig
from pamd.loop.control.onoff import EXHAUST, HOLD, INFLATE, Pulser, SlidingModePosition
from pamd.loop.control.valve_pulse import TAKEN, ValvePulse
from pamd.loop.devices.bindings import MuscleSignals, OutputBinding
from pamd.wire.tick import Flag, MuscleTick

F_EXHAUST = int(Flag.EXHAUST_OPEN)
F_INFLATE = int(Flag.INFLATE_OPEN)


class SafeOutput(NamedTuple):
    """What one output holds in the safe state, in SI (for devices that fall back to
    preset outputs by themselves: `pamd.drivers.safe_outputs`)."""

    binding: OutputBinding
    value: float
    unit: str  # "bar", or "(1 = open)" for a valve


class Actuation(Protocol):
    """How one muscle's command reaches its valves."""

    exhaust_open: bool  # the exhaust valve is open (vented)
    #: The valves close the pressure loop themselves (the muscle's PID adds nothing).
    closes_pressure_loop: bool
    #: In mode position the valves position the length themselves
    #: (`pamd.loop.control.setpoint.ValvesPosition`).
    positions_length: bool

    @property
    def switch_count(self) -> int:
        """Valve switches since start, every valve (the record and the summary)."""
        ...

    def update(self, t: MuscleTick, now_s: float, dt_s: float) -> None:
        """Drive the outputs for this tick from the muscle's `MuscleTick`: the limited
        command (`command_bar`), the pressure to act on (`valve_pressure_bar`, NaN:
        none, the air is held), whether to vent (`vent`: the safe pressure is 0 and the
        command reached it), the pressure not to vent below (`valve_floor_bar`, a safe
        state's) and, where the valves position the length (`position_valves`), the
        length, its target and the pressure not to fill above (`ceiling_bar`). ORs the
        record's flag bits it sets into `t.flags` (EXHAUST_OPEN, INFLATE_OPEN); a fault
        of its own (valves that do not act) into `t.fault` and `t.finding`. Tick path:
        never blocks, allocates nothing."""
        ...

    def safe_outputs(self, safe_pressure_bar: float) -> list[SafeOutput]:
        """What each output holds in the safe state with this safe pressure."""
        ...

    def switches(self) -> dict[str, int]:
        """Switchings per valve since start (the summary and the recording)."""
        ...


#: Exhaust assist: the exhaust valve opens with the pressure this far above the command,
#: and shuts once it is within ASSIST_CLOSE_BAR (hysteresis against chatter).
ASSIST_OPEN_BAR = 0.1
ASSIST_CLOSE_BAR = 0.03


class RegulatorActuation:
    """A proportional pressure regulator's setpoint, plus the optional exhaust
    valve: open to vent to a safe pressure of 0 (`vent`), and, with an exhaust assist,
    while a command below `assist_below_bar` stands well under the measured pressure
    (a regulator alone vents ever slower as the pressure nears the atmosphere's)."""

    closes_pressure_loop = False
    positions_length = False

    def __init__(self, valve: OutputBinding, exhaust: OutputBinding | None,
                 assist_below_bar: float | None = None) -> None:
        self.valve = valve
        self.exhaust = exhaust
        self.exhaust_open = False
        self.switch_count = 0
        self.assist_below_bar = -math.inf if assist_below_bar is None else assist_below_bar

    def update(self, t: MuscleTick, now_s: float, dt_s: float) -> None:
        command_bar = t.command_bar
        self.valve.write_si(command_bar)
        exhaust = self.exhaust
        if exhaust is None:
            return
        vent = t.vent
        if not vent and command_bar < self.assist_below_bar:
            gap = t.valve_pressure_bar - command_bar  # NaN (untrusted pressure): shut
            vent = gap > ASSIST_OPEN_BAR or (self.exhaust_open and gap > ASSIST_CLOSE_BAR)
        if vent != self.exhaust_open:
            exhaust.write_si(1.0 if vent else 0.0)
            self.exhaust_open = vent
            self.switch_count += 1
        if vent:
            t.flags |= F_EXHAUST

    def switches(self) -> dict[str, int]:
        return {} if self.exhaust is None else {"exhaust": self.switch_count}

    def safe_outputs(self, safe_pressure_bar: float) -> list[SafeOutput]:
        out = [SafeOutput(self.valve, safe_pressure_bar, "bar")]
        if self.exhaust is not None:
            out.append(SafeOutput(self.exhaust, 1.0 if safe_pressure_bar == 0.0 else 0.0,
                                  "(1 = open)"))
        return out


#: A command moving slower than this counts as steady (the dead band applies).
STEADY_BAR_PER_S = 0.01
#: The integral's clamp (bar of pressure error).
INTEGRAL_LIMIT_BAR = 0.5
INTEGRAL_TIMES = 5.0  # integral time = this x response_s


def min_pulse_s(cfg: OnOffConfig) -> float:
    """The shortest pulse worth sending: twice the opening delay (a pulse taken back
    within the delay never moves the spool), at least 2 ms, within the period."""
    pulse = max(2.0 * cfg.valve_on_delay_s, 0.002)
    return min(pulse, 0.5 * cfg.pwm_period_s)


#: A valve that has been open this long (in all, since the pressure last moved its way
#: by VALVE_MOVE_BAR) does not act: stuck, no supply, or a blocked line.
VALVE_OPEN_S = 1.0
VALVE_MOVE_BAR = 0.05
#: Held this long, both valves shut, the count starts again.
VALVE_REST_S = 0.5
#: Below this pressure an open exhaust need not lower it any further.
VENTED_BAR = 0.2


class OnOffActuation:
    """An inflate (3/2 NC) and an exhaust (2/2 NC) valve driven by PWM."""

    closes_pressure_loop = True  # the PWM law is the pressure loop (module docstring)
    positions_length = True  # seed 004's sliding mode in mode position

    def __init__(self, inflate: OutputBinding, exhaust: OutputBinding,
                 cfg: OnOffConfig, *, muscle: str) -> None:
        self.inflate = inflate
        self.exhaust = exhaust
        self.pulser = Pulser(cfg.pwm_period_s, min_pulse_s(cfg))
        self.sliding = SlidingModePosition(
            lambda_per_s=cfg.position_lambda_per_s, boundary_mm_s=cfg.position_boundary_mm_s,
            hold_band_mm=cfg.position_hold_band_mm, period_s=cfg.position_period_s,
            min_pulse_s=min(min_pulse_s(cfg), 0.5 * cfg.position_period_s))
        self._positioning = False
        self._length_mm = self._velocity_mm_s = 0.0
        self._target_mm = self._target_rate_mm_s = 0.0
        self._ceiling_bar = 0.0
        self.set_config(cfg)
        self.exhaust_open = False
        self.inflate_open = False
        self.inflate_switches = 0
        self.exhaust_switches = 0
        self.integral_bar = 0.0
        self.duty = 0.0
        self.state = HOLD
        self._prev_command = float("nan")
        self._p_filtered = float("nan")
        self._holding = False
        self._tau_s = cfg.pwm_period_s
        self._alpha = 0.0
        # the valves' own check: open time without the pressure moving their way
        self.name = muscle  # the fault names the muscle (channel names are the driver's)
        self._watched = HOLD
        self._open_s = 0.0
        self._rest_s = 0.0
        self._p_ref = float("nan")
        self._fault: str | None = None
        self._floor_bar = -math.inf  # the safe state's floor, this tick (valve_floor_bar)
        self.pulse = ValvePulse()  # pamd tune --loop onoff's step test

    def set_config(self, cfg: OnOffConfig) -> None:
        """Gains from the config (also a reload's; the state stays)."""
        self.fill_rate = cfg.fill_rate_bar_per_s
        self.vent_rate = cfg.vent_rate_bar_per_s
        self.response_s = cfg.response_s
        self.integral_time_s = INTEGRAL_TIMES * cfg.response_s
        self.dead_band_bar = cfg.dead_band_bar
        # what still drains after the exhaust is told to close, plus the dead band
        self.floor_margin_bar = cfg.vent_rate_bar_per_s * cfg.valve_off_delay_s + cfg.dead_band_bar

    @property
    def switch_count(self) -> int:
        return self.inflate_switches + self.exhaust_switches

    @property
    def holding(self) -> bool:
        """The PWM holds both valves at rest: the pressure within the dead band of a
        steady command."""
        return self._holding

    def switches(self) -> dict[str, int]:
        """Switchings per valve (the summary and the recording)."""
        return {"inflate": self.inflate_switches, "exhaust": self.exhaust_switches}

    def reset(self) -> None:
        self.pulser.reset()
        self.integral_bar = 0.0
        self._prev_command = float("nan")
        self._p_filtered = float("nan")
        self._holding = False

    def update(self, t: MuscleTick, now_s: float, dt_s: float) -> None:
        """The tick (`Actuation.update`). In mode position (`t.position_valves`) the
        valves follow seed 004's sliding mode on the length instead of the command,
        never filling above `t.ceiling_bar` (the pressure limit and the guards'); in a
        safe state they never vent the muscle below `t.valve_floor_bar` (its safe
        pressure). A valve that does not act (`_watch`) is this stage's fault: in mode
        position the command is the measured pressure, so the pressure tracking check
        cannot see it."""
        positioning = self._positioning = t.position_valves
        if positioning:
            self._length_mm = t.length_mm
            self._velocity_mm_s = t.velocity_mm_s
            self._target_mm = t.target_length_mm
            self._target_rate_mm_s = t.target_rate_mm_s
            self._ceiling_bar = t.ceiling_bar
        self._floor_bar = t.valve_floor_bar
        pressure_bar = t.valve_pressure_bar
        state = self._choose(t.command_bar, pressure_bar, now_s, dt_s, t.vent)
        self._watch(state, pressure_bar, dt_s)
        t.flags |= self._set(state)
        fault = self._fault
        if fault is not None:  # once; the check then starts again
            self._fault = None
            t.fault = t.finding = fault

    def _watch(self, state: int, p: float, dt_s: float) -> None:
        """A valve open for VALVE_OPEN_S in all without the pressure moving its way by
        VALVE_MOVE_BAR does not act. Float arithmetic only (the tick path)."""
        if p != p:  # no trusted pressure: nothing to judge
            self._open_s = 0.0
            self._p_ref = p
            return
        if state == HOLD:
            self._rest_s += dt_s
            if self._rest_s >= VALVE_REST_S:
                self._open_s = 0.0
            return
        self._rest_s = 0.0
        ref = self._p_ref
        if state != self._watched or ref != ref:
            self._watched, self._p_ref, self._open_s = state, p, 0.0
            return
        if state == INFLATE:
            if p >= ref + VALVE_MOVE_BAR:
                self._p_ref, self._open_s = p, 0.0
                return
            if p < ref:
                self._p_ref = p  # a rise counts from the lowest pressure since
        else:
            if p <= ref - VALVE_MOVE_BAR or p < VENTED_BAR:
                self._p_ref, self._open_s = p, 0.0
                return
            if p > ref:
                self._p_ref = p
        self._open_s += dt_s
        if self._open_s >= VALVE_OPEN_S and self._fault is None:
            self._not_acting(state, p)

    def _not_acting(self, state: int, p: float) -> None:
        """The valve open in `state` has not moved the pressure (fault path): said, and
        the watch starts again."""
        valve = "inflate" if state == INFLATE else "exhaust"
        way = "rising" if state == INFLATE else "falling"
        self._fault = (f"{self.name}: the pressure does not follow the {valve} valve: "
                       f"open {self._open_s:.1f} s without {way} ({p:.2f} bar; stuck "
                       "valve, no supply or a blocked line?)")
        self._open_s = 0.0
        self._p_ref = p

    def _choose(self, command_bar: float, pressure_bar: float, now_s: float, dt_s: float,
                vent: bool) -> int:
        """The valves' state this tick (INFLATE, HOLD or EXHAUST)."""
        prev = self._prev_command
        self._prev_command = command_bar
        positioning = self._positioning
        self._positioning = False
        floor = self._floor_bar
        self._floor_bar = -math.inf
        pulse = self.pulse
        if pulse.active:
            if floor > 0.0 or vent or positioning:
                pulse.stop(TAKEN)
            else:  # the step test holds the valves; then the PWM goes on from its own
                self.pulser.reset()  # hold (within twice its dead band) or a new period
                self._p_filtered = pressure_bar
                self.duty = 0.0
                return pulse.step(command_bar, pressure_bar, dt_s)
        if floor > 0.0:
            state = self._pwm(command_bar, pressure_bar, now_s, dt_s, prev)
            if pressure_bar <= floor + self.floor_margin_bar:
                if self.integral_bar < 0.0:
                    self.integral_bar = 0.0  # nothing wound up holds it down
                if state == EXHAUST:
                    self.pulser.reset()
                    self.duty = 0.0
                    return HOLD
            return state
        if vent:
            self.integral_bar = 0.0
            self.duty = -1.0
            return EXHAUST
        if positioning:
            state = self.sliding.step(now_s, self._length_mm, self._velocity_mm_s,
                                      self._target_mm, self._target_rate_mm_s)
            if state == INFLATE and not pressure_bar < self._ceiling_bar:
                state = HOLD  # the limit and the guards bound the valves too
            self.pulser.reset()
            self._holding = False
            self.integral_bar = 0.0
            self.duty = self.sliding.surface
            return state
        return self._pwm(command_bar, pressure_bar, now_s, dt_s, prev)

    def _pwm(self, command_bar: float, pressure_bar: float, now_s: float, dt_s: float,
             prev: float) -> int:
        """The PWM pressure law (the module's docstring) toward `command_bar`."""
        rate = 0.0 if prev != prev else (command_bar - prev) / dt_s
        self._alpha = dt_s / (self._tau_s + dt_s)
        e = command_bar - pressure_bar
        if e != e:  # no trusted pressure to act on: hold the air in
            self.pulser.reset()
            self.duty = 0.0
            return HOLD
        # The dead band, on the pressure low-passed over a PWM period (the sensor's
        # noise alone never opens a valve), with hysteresis: entered within the band
        # once a pulse is over, left beyond twice the band.
        pf = self._p_filtered
        pf = pressure_bar if pf != pf else pf + self._alpha * (pressure_bar - pf)
        self._p_filtered = pf
        ef = command_bar - pf
        band = self.dead_band_bar
        if -STEADY_BAR_PER_S < rate < STEADY_BAR_PER_S:
            if self._holding:
                self._holding = -2.0 * band <= ef <= 2.0 * band
            else:
                self._holding = -band <= ef <= band and not self.pulser.pulsing(now_s)
        else:
            self._holding = False
        if self._holding:
            self.pulser.reset()
            self.duty = 0.0
            return HOLD
        i = self.integral_bar + e * dt_s / self.integral_time_s
        self.integral_bar = (INTEGRAL_LIMIT_BAR if i > INTEGRAL_LIMIT_BAR
                             else (-INTEGRAL_LIMIT_BAR if i < -INTEGRAL_LIMIT_BAR else i))
        want = (e + self.integral_bar) / self.response_s + rate
        duty = want / self.fill_rate if want > 0.0 else want / self.vent_rate
        self.duty = duty
        return self.pulser.state(now_s, duty)

    def _set(self, state: int) -> int:
        """Drive both valves to `state`; writes and counts only what changes."""
        self.state = state
        inflate = state == INFLATE
        exhaust = state == EXHAUST
        if inflate != self.inflate_open:
            self.inflate.write_si(1.0 if inflate else 0.0)
            self.inflate_open = inflate
            self.inflate_switches += 1
        if exhaust != self.exhaust_open:
            self.exhaust.write_si(1.0 if exhaust else 0.0)
            self.exhaust_open = exhaust
            self.exhaust_switches += 1
        return F_EXHAUST if exhaust else (F_INFLATE if inflate else 0)

    def safe_outputs(self, safe_pressure_bar: float) -> list[SafeOutput]:
        """Both closed holds the air in; at a safe pressure of 0 the exhaust vents."""
        vent = 1.0 if safe_pressure_bar == 0.0 else 0.0
        return [SafeOutput(self.inflate, 0.0, "(1 = open)"),
                SafeOutput(self.exhaust, vent, "(1 = open)")]


def actuation_for(signals: MuscleSignals, muscle: MuscleConfig) -> Actuation:
    """The actuation a muscle's config describes: a regulator (and its optional exhaust)
    or on/off valves (both required by the config's rules: pamd.config.actuation_rules)."""
    if muscle.actuation == "onoff":
        if signals.inflate is None or signals.exhaust is None:
            raise ValueError(f"muscle {muscle.name!r}: on/off actuation needs its inflate "
                             "and exhaust outputs")
        return OnOffActuation(signals.inflate, signals.exhaust, muscle.onoff,
                              muscle=muscle.name)
    if signals.valve is None:
        raise ValueError(f"muscle {muscle.name!r}: a regulator needs its valve output")
    return RegulatorActuation(signals.valve, signals.exhaust, muscle.exhaust_assist_below_bar)
