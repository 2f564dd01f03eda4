"""The reference stage of one muscle's tick: the pressure setpoint, chosen by mode.

* `SafeRamp`: in a safe state (FAULT, ESTOP, a safe ramp after a stop, a deadman or
  a start-up outside the limits) the setpoint ramps to the safe pressure at the slew
  limit; in ESTOP at the ESTOP slew, held (`estop_action: hold`) or vented at once
  (`vent`, only where the safe pressure is 0).
* `ProfileFollower`: a pressure profile (or a setpoint's ramp) while RUNNING or
  LOAD_CHANGE, at most at the slew limit.
* the length modes: `pamd.control.length_control.LengthControl`.

Each `step` takes the present setpoint and returns this tick's; the setpoint's
rate (for the pressure loop's rate feedforward) is left in `rate_bar_per_s`.
Tick path: float arithmetic only.
"""

from __future__ import annotations

import math

from pamd.profiles import Profile
from pamd.safety.envelope import MuscleEnvelope
from pamd.tick import Flag

F_SLEW = int(Flag.SLEW_LIMITED)


class SafeRamp:
    """The setpoint of a safe state."""

    def __init__(self, envelope: MuscleEnvelope) -> None:
        self.set_envelope(envelope)
        self.rate_bar_per_s = 0.0
        self.slew_bar_per_s = self._slew  # the slew limit this tick (ESTOP's, inf: vent)

    def set_envelope(self, envelope: MuscleEnvelope) -> None:
        self._slew = envelope.safe_slew_bar_per_s
        self._estop_slew = envelope.estop_slew_bar_per_s
        self._estop_holds = envelope.estop_action == "hold"
        self._estop_vents = envelope.estop_action == "vent"

    def step(self, setpoint_bar: float, safe_pressure_bar: float, estop: bool,
             dt: float) -> float:
        sp = setpoint_bar
        slew = self._slew
        target = safe_pressure_bar
        if estop:
            slew = self._estop_slew
            if self._estop_holds:
                target = sp
            elif self._estop_vents and target == 0.0:
                sp = 0.0  # vent at once: only where the load allows it
                slew = math.inf
        self.slew_bar_per_s = slew
        step = slew * dt
        if sp < target - step:
            self.rate_bar_per_s = slew
            return sp + step
        if sp > target + step:
            self.rate_bar_per_s = -slew
            return sp - step
        self.rate_bar_per_s = 0.0
        return target


class ProfileFollower:
    """The setpoint of a running pressure profile, slew-limited."""

    def __init__(self, envelope: MuscleEnvelope) -> None:
        self.set_envelope(envelope)
        self.rate_bar_per_s = 0.0
        self.flags = 0

    def set_envelope(self, envelope: MuscleEnvelope) -> None:
        self._slew = envelope.slew_limit_bar_per_s

    def step(self, profile: Profile, now: float, setpoint_bar: float, dt: float) -> float:
        profile.sample(now)
        want = profile.value
        slew = self._slew
        step = slew * dt
        sp = setpoint_bar
        if want > sp + step:
            self.flags = F_SLEW
            self.rate_bar_per_s = slew
            return sp + step
        if want < sp - step:
            self.flags = F_SLEW
            self.rate_bar_per_s = -slew
            return sp - step
        self.flags = 0
        self.rate_bar_per_s = profile.rate
        return want
