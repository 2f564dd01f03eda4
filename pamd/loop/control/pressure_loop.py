"""The pressure stage of one muscle's tick: the PID pressure loop (`pamd.loop.control.pid`)
plus the rate feedforward (`control.rate_feedforward_s` times the setpoint's rate), or,
while `pamd tune --method relay` runs, the relay test (`pamd.loop.control.relay`) in their
place.

It closes its loop only on a trusted pressure and outside FAULT/ESTOP; otherwise
the command is the setpoint itself (open loop, e.g. to the safe pressure) and the
PID waits, reset, for a bumpless return. Where the loop opens because the pressure
became untrusted or a fault was found, the setpoint may lie far from the PID's last
output (a sensor reading low had the PID hold the command above it): the limiter,
with that tick counted as the safe state's entry, moves the command from its last
value at the safe slew, never below min(safe pressure, that value). After the
limiter has clamped the command (`unwind`), the integral may move away from the
clamp, never into it. While the supply is out (`hold_integral`, the safety chain's
supply input: `pamd.loop.safety.chain`) the integral holds: the pressure cannot follow
without air, and a PID that integrated that error would have wound up by the time
the air returns.
Tick path: float arithmetic only.
"""

from __future__ import annotations

import math

from pamd.config.control_schema import PidConfig
from pamd.loop.control.pid import Pid
from pamd.loop.control.relay import Relay
from pamd.wire.tick import Flag, MuscleTick, State

F_SAT = int(Flag.OUTPUT_SATURATED)
S_FAULT, S_ESTOP = int(State.FAULT), int(State.ESTOP)


class PressureLoop:
    """PID + rate feedforward of one muscle."""

    def __init__(self, gains: PidConfig, rate_feedforward_s: float) -> None:
        self.pid = Pid(gains.kp, gains.ki_per_s, gains.kd_s, gains.derivative_filter_hz,
                       gains.integral_limit_bar, gains.output_limit_bar)
        self.rate_feedforward_s = rate_feedforward_s
        self.closed = False  # the loop was closed this tick
        self.flags = 0
        self._i_before = 0.0
        self.hold_integral = False  # the supply is out: the integral holds
        self.relay = Relay()

    def set_gains(self, gains: PidConfig, rate_feedforward_s: float) -> None:
        """A reload's gains; the PID keeps its state, the integral clamped to the new
        limit: no bump."""
        pid = self.pid
        pid.kp, pid.ki, pid.kd = gains.kp, gains.ki_per_s, gains.kd_s
        pid.filter_tau_s = 1.0 / (2.0 * math.pi * gains.derivative_filter_hz)
        pid.integral_limit, pid.output_limit = gains.integral_limit_bar, gains.output_limit_bar
        pid.i = max(-pid.integral_limit, min(pid.integral_limit, pid.i))
        self.rate_feedforward_s = rate_feedforward_s

    def reset(self, measured_bar: float, integral_bar: float = 0.0) -> None:
        self.pid.reset(measured_bar, integral_bar)

    def update(self, t: MuscleTick, now: float, dt: float) -> None:
        """The command control wants (`t.command_bar`, before the guards and the
        limiter), closed on a trusted pressure, outside FAULT/ESTOP and not while the
        safe ramp vents (at a safe pressure of 0 a PID on the sensor's noise would lift
        the command off 0 and make the exhaust chatter); closed, plus the setpoint
        source's flow term."""
        state, ok = t.state, t.pressure_ok
        close = ok and not (state == S_FAULT or state == S_ESTOP or t.venting)
        if close and not (self.relay.active or self.hold_integral):
            # the common path: `step`'s closed loop, inline (one call less a tick)
            pid = self.pid
            self.closed = True
            self._i_before = pid.i
            setpoint, p = t.setpoint_bar, t.pressure_bar
            u = setpoint + self.rate_feedforward_s * t.rate_bar_per_s + pid.step(setpoint - p, p,
                                                                                 dt)
            self.flags = flags = F_SAT if pid.saturated else 0
        else:
            u = self.step(t.setpoint_bar, t.rate_bar_per_s, t.pressure_bar, close, ok, dt)
            flags = self.flags
        flow = t.flow_bar
        if flow != 0.0 and self.closed:
            u += flow  # the air the planned motion draws (position mode)
        t.command_bar = u
        t.flags |= flags

    def step(self, setpoint_bar: float, rate_bar_per_s: float, pressure_bar: float,
             close: bool, pressure_ok: bool, dt: float) -> float:
        """The command control wants (before the guards and the limiter), bar."""
        pid = self.pid
        self.closed = close
        relay = self.relay
        if relay.active:
            if close and setpoint_bar == relay.center_bar:
                pid.reset(pressure_bar)  # bumpless when the relay ends
                self._i_before = 0.0
                self.flags = 0
                return relay.step(pressure_bar, dt)
            if not close:
                relay.stop("the pressure loop opened (untrusted pressure, a fault)")
            elif relay.elapsed_s > 0.0:  # armed and still ramping to the center: wait
                relay.stop("the setpoint moved (a command, a stop or the safe state)")
        if close:
            self._i_before = pid.i
            u = (setpoint_bar + self.rate_feedforward_s * rate_bar_per_s
                 + pid.step(setpoint_bar - pressure_bar, pressure_bar, dt))
            if self.hold_integral:  # no air: the error is not the loop's to integrate
                u -= pid.i - self._i_before
                pid.i = self._i_before
            self.flags = F_SAT if pid.saturated else 0
            return u
        self._i_before = 0.0
        pid.reset(pressure_bar if pressure_ok else setpoint_bar)
        self.flags = 0
        return setpoint_bar

    def unwind(self, command_bar: float, wanted_bar: float) -> None:
        """The limiter moved the command from `wanted_bar` to `command_bar`."""
        if self.closed:
            self.pid.keep_integral_off_clamp(self._i_before, command_bar < wanted_bar)
