"""The setpoint stage of one muscle's tick: the pressure setpoint, chosen by mode.

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
    """The setpoint of a safe state.

    Its pace is the rig's (`pace`, by `pamd.controller.RigController.enter_safe_state`):
    every muscle's ramp lasts as long as the longest, each at most at its own slew
    limit, so that the muscles of a rig reach their safe pressures together (an
    antagonistic pair never slams its joint by one muscle ramping alone). A ramp that
    reaches its target, or starts afresh, goes at its own slew limit again."""

    def __init__(self, envelope: MuscleEnvelope) -> None:
        self.set_envelope(envelope)
        self.rate_bar_per_s = 0.0
        self.slew_bar_per_s = self._slew  # the slew limit this tick (ESTOP's, inf: vent)
        self._paced_bar_per_s = math.inf  # the rig's pace for this ramp (inf: none)

    def time_to_target_s(self, setpoint_bar: float, safe_pressure_bar: float,
                         estop: bool) -> float:
        """How long the ramp from `setpoint_bar` takes at its own slew limit."""
        target, slew = self._target_and_slew(setpoint_bar, safe_pressure_bar, estop)
        if slew == math.inf:
            return 0.0
        return abs(target - setpoint_bar) / slew

    def pace(self, setpoint_bar: float, safe_pressure_bar: float, estop: bool,
             duration_s: float) -> None:
        """Ramp from `setpoint_bar` in `duration_s` (at least its own time: never faster
        than its slew limit); a duration of 0 leaves its own pace."""
        target, _ = self._target_and_slew(setpoint_bar, safe_pressure_bar, estop)
        if duration_s > 0.0:
            self._paced_bar_per_s = abs(target - setpoint_bar) / duration_s
        else:
            self._paced_bar_per_s = math.inf

    def unpace(self) -> None:
        self._paced_bar_per_s = math.inf

    def _target_and_slew(self, sp: float, safe_pressure_bar: float,
                         estop: bool) -> tuple[float, float]:
        if not estop:
            return safe_pressure_bar, self._slew
        if self._estop_holds:
            return sp, self._estop_slew
        if self._estop_vents and safe_pressure_bar == 0.0:
            return 0.0, math.inf
        return safe_pressure_bar, self._estop_slew

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
        self.slew_bar_per_s = slew  # what the limiter holds the command to
        pace = self._paced_bar_per_s
        if pace < slew:
            slew = pace
        step = slew * dt
        if sp < target - step:
            self.rate_bar_per_s = slew
            return sp + step
        if sp > target + step:
            self.rate_bar_per_s = -slew
            return sp - step
        self.rate_bar_per_s = 0.0
        self._paced_bar_per_s = math.inf  # there: a new target goes at the slew limit
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
