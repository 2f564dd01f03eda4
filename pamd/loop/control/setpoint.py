"""The setpoint stage of one muscle's tick: where the pressure setpoint comes from.

Each is a source with one update signature (`pamd.wire.tick.Stage`: `update(t, now, dt)` on
the muscle's `MuscleTick`), chosen by the muscle when its mode or the rig's state
changes (`pamd.loop.control.muscle.MuscleController`), never branched on per tick:

* `SafeRamp`: in a safe state (FAULT, ESTOP, a safe ramp after a stop, a deadman or
  a start-up outside the limits) the setpoint ramps to the safe pressure at the slew
  limit; in ESTOP at the ESTOP slew, held (`estop_action: hold`) or vented at once
  (`vent`, only where the safe pressure is 0).
* `AirHold`: in FAULT or ESTOP with the air cut (the safety chain opened, the supply
  lost): the command holds the pressure the muscle holds, coming down with it while
  the air is out, never up.
* `ProfileFollower`: a pressure profile (or a setpoint's ramp) while RUNNING or
  LOAD_CHANGE, at most at the slew limit.
* `Hold`: nothing runs (IDLE, HOLD, a finished profile stopped): the setpoint stays.
* the length modes: `pamd.loop.control.length_control.LengthControl`, and `ValvesPosition`
  where the valves position the length themselves (on/off valves in mode position).

Each takes the present setpoint (`t.setpoint_bar`) and leaves this tick's, with its
rate (for the pressure loop's rate feedforward) in `t.rate_bar_per_s`; what is fixed
for as long as a source is chosen (whether it is a safe state's, its slew outside a
safe ramp) the muscle sets when it chooses it. Tick path: float arithmetic only.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

from pamd.loop.safety.envelope import MuscleEnvelope
from pamd.profiles import Profile
from pamd.wire.tick import Flag, MuscleTick

if TYPE_CHECKING:
    from pamd.loop.control.length_control import LengthControl
    from pamd.loop.safety.plausibility import Plausibility

F_SLEW = int(Flag.SLEW_LIMITED)
#: Setpoint and command at or below this, with a safe pressure of 0: vent.
VENT_BELOW_BAR = 0.005


class SafeRamp:
    """The setpoint of a safe state.

    Its pace is the rig's (`pace`, by `pamd.loop.control.rig_safe_state.pace_safe_entry`):
    every muscle's ramp lasts as long as the longest, each at most at its own slew
    limit, so that the muscles of a rig reach their safe pressures together (an
    antagonistic pair never slams its joint by one muscle ramping alone). A ramp that
    reaches its target, or starts afresh, goes at its own slew limit again.

    At a safe pressure of 0, once the setpoint is there, it vents (`t.venting`): the
    pressure loop stays open and the exhaust opens."""

    def __init__(self, envelope: MuscleEnvelope) -> None:
        self.set_envelope(envelope)
        self.rate_bar_per_s = 0.0
        self.slew_bar_per_s = self._slew  # the slew limit this tick (ESTOP's, inf: vent)
        self._paced_bar_per_s = math.inf  # the rig's pace for this ramp (inf: none)
        self.safe_pressure_bar = 0.0  # the muscle's (`MuscleController.set_load`)
        self.estop = False  # the rig is in ESTOP (set when chosen)

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

    def _target_and_slew(self, setpoint: float, safe_pressure_bar: float,
                         estop: bool) -> tuple[float, float]:
        if not estop:
            return safe_pressure_bar, self._slew
        if self._estop_holds:
            return setpoint, self._estop_slew
        if self._estop_vents and safe_pressure_bar == 0.0:
            return 0.0, math.inf
        return safe_pressure_bar, self._estop_slew

    def set_envelope(self, envelope: MuscleEnvelope) -> None:
        self._slew = envelope.safe_slew_bar_per_s
        self._estop_slew = envelope.estop_slew_bar_per_s
        self._estop_holds = envelope.estop_action == "hold"
        self._estop_vents = envelope.estop_action == "vent"

    def update(self, t: MuscleTick, now: float, dt: float) -> None:
        setpoint = t.setpoint_bar
        target = self.safe_pressure_bar
        if self.estop:
            setpoint, target, slew = self._estop_step(setpoint, target)
        else:
            slew = self._slew
        self.slew_bar_per_s = t.slew_bar_per_s = slew  # what the limiter holds it to
        pace = self._paced_bar_per_s
        if pace < slew:
            slew = pace
        step = slew * dt
        if setpoint < target - step:
            rate, setpoint = slew, setpoint + step
        elif setpoint > target + step:
            rate, setpoint = -slew, setpoint - step
        else:
            rate, setpoint = 0.0, target
            self._paced_bar_per_s = math.inf  # there: a new target goes at the slew limit
        self.rate_bar_per_s = t.rate_bar_per_s = rate
        t.setpoint_bar = setpoint
        t.venting = self.safe_pressure_bar == 0.0 and setpoint <= VENT_BELOW_BAR

    def _estop_step(self, setpoint: float, target: float) -> tuple[float, float, float]:
        """ESTOP's action: (setpoint, target, slew)."""
        if self._estop_holds:
            return setpoint, setpoint, self._estop_slew
        if self._estop_vents and target == 0.0:
            return 0.0, target, math.inf  # vent at once: only where the load allows it
        return setpoint, target, self._estop_slew


class AirHold:
    """The setpoint while the air is cut (the safety chain opened, the supply lost) in
    FAULT or ESTOP: `hold_bar`, the pressure the muscle holds (`MuscleController.
    hold_air` sets it, `known_pressure_bar`). While the air is out (`out`) it comes
    down with the pressure the muscle holds, on a trusted reading (`follow`): the
    higher of the reading and its low-pass, above the pressure whether it rises or
    falls, so the command's descent vents nothing and ratchets nothing. It never rises
    until the operator's reset (`release`)."""

    def __init__(self, plausibility: Plausibility) -> None:
        self.plausibility = plausibility
        self.hold_bar = math.nan  # NaN: not holding the air
        self.out = False  # the supply is out

    @property
    def holding(self) -> bool:
        return self.hold_bar == self.hold_bar

    def follow(self, pressure_bar: float) -> None:
        """Down with `pressure_bar`, never up."""
        if pressure_bar < self.hold_bar:
            self.hold_bar = pressure_bar if pressure_bar > 0.0 else 0.0

    def release(self) -> None:
        self.hold_bar = math.nan

    def update(self, t: MuscleTick, now: float, dt: float) -> None:
        if self.out and t.pressure_ok:  # the air out: down with the pressure held
            p = t.pressure_bar
            lp = self.plausibility.pressure_lowpass_bar
            self.follow(lp if lp > p else p)
        t.setpoint_bar = self.hold_bar


class ProfileFollower:
    """The setpoint of a running pressure profile (`profile`, set when chosen),
    slew-limited."""

    def __init__(self, envelope: MuscleEnvelope) -> None:
        self.set_envelope(envelope)
        self.profile: Profile | None = None

    def set_envelope(self, envelope: MuscleEnvelope) -> None:
        self._slew = envelope.slew_limit_bar_per_s

    def update(self, t: MuscleTick, now: float, dt: float) -> None:
        profile = self.profile
        assert profile is not None  # chosen with one
        profile.evaluate(now, profile)  # `Profile.sample`, one call less
        want = profile.value
        slew = self._slew
        step = slew * dt
        setpoint = t.setpoint_bar
        if want > setpoint + step:
            t.flags |= F_SLEW
            t.rate_bar_per_s = slew
            t.setpoint_bar = setpoint + step
        elif want < setpoint - step:
            t.flags |= F_SLEW
            t.rate_bar_per_s = -slew
            t.setpoint_bar = setpoint - step
        else:
            t.rate_bar_per_s = profile.rate
            t.setpoint_bar = want


class Hold:
    """Nothing runs: the setpoint stays where it is, at rate 0 (set when chosen)."""

    def update(self, t: MuscleTick, now: float, dt: float) -> None:
        return None


class ValvesPosition:
    """A length mode where the valves position the length themselves (on/off valves in
    mode position, seed 004's sliding mode in `pamd.loop.control.actuation.OnOffActuation`):
    the length control still moves the targets; the pressure is whatever the valves'
    motion takes, so on a trusted pressure the setpoint is the measured pressure (the
    tracking check holds, the record has no pressure setpoint: `t.positioning`)."""

    def __init__(self, length_control: LengthControl) -> None:
        self.length_control = length_control

    def update(self, t: MuscleTick, now: float, dt: float) -> None:
        self.length_control.update(t, now, dt)
        t.flow_bar = 0.0  # the valves close the pressure loop: no flow term
        if t.pressure_ok:
            t.setpoint_bar = t.pressure_bar
            t.rate_bar_per_s = 0.0
