"""The limiter: the supervisor's invariants on one muscle's valve command, applied
last, after the reference, the PID and every guard. Nothing downstream of it
changes the command.

Always: the command is never above the pressure limit (a command that starts above
it, e.g. a pressure held at start-up, comes down at the slew limit) and never
below 0.

In a safe state (FAULT, ESTOP, a safe ramp: a stop, a deadman, a start-up outside
the limits):

* the command moves at most at the safe slew (the ESTOP slew in ESTOP);
* it never falls below the safe pressure; a command still below it (the safe
  state began lower) never falls at all, it only rises towards it.

The safe state's entry counts as the safe state: the tick that finds a fault (the
supervisor latches it at once) or loses its pressure (the pressure loop opens there,
and its command would jump from the PID's output to the setpoint) is held to these
invariants from the command written last, whichever signal failed
(`pamd.control.muscle.MuscleController.tick`). So the entry never takes the command
below min(safe pressure, the command at entry) nor faster than the safe slew
(`safety.safe_slew_bar_per_s`). Every path that moves the rig (`pamd run`, `pamd
tune`, `pamd collect`, remote commands and collections) reaches the valves through
this one limiter.

The one exception is an ESTOP whose action is `vent`, honoured only where the safe
pressure is 0 (the load needs no pressure): the command drops to 0 at once and
the exhaust opens (the caller passes a floor of 0 and an unlimited step).
"""

from __future__ import annotations

from pamd.tick import Flag

F_SOFT_P, F_SLEW = int(Flag.SOFT_LIMIT_PRESSURE), int(Flag.SLEW_LIMITED)
F_SOFT_C, F_PRETENSION = int(Flag.SOFT_LIMIT_CONTRACTION), int(Flag.PRETENSION_LIMIT)

HELD_BACK_BAR = 0.005
"""A command clamped at the pressure limit holds the reference back only where the
setpoint itself asks for more than the command by this much; the top of a profile that
reaches the limit, where only the PID's correction is trimmed, is not held back."""


def held_back(flags: int, setpoint_bar: float, command_bar: float) -> bool:
    """Whether a limit or guard held the reference back this tick (what the summary
    counts and a `soft_limit` event reports): a contraction or pretension guard, or
    the pressure limit below the setpoint."""
    return bool(flags & (F_SOFT_C | F_PRETENSION)) or (
        bool(flags & F_SOFT_P) and setpoint_bar > command_bar + HELD_BACK_BAR)


class Limiter:
    """Applies the invariants; `flags` holds the bits of the last `apply`."""

    def __init__(self) -> None:
        self.flags = 0

    def apply(self, u: float, prev: float, max_p: float, lo: float, hi: float, safe: bool,
              floor: float, step: float) -> float:
        """The command to write. `u` is what control wants, `prev` the last command
        written, `lo`/`hi` the guards' bounds (restoring direction only), `safe` whether a
        safe state holds, `floor` its safe pressure, `step` the slew limit times the
        period."""
        flags = 0
        if u > hi:
            u = hi
        if u < lo:
            u = lo
        if u > max_p:
            u = max_p
            flags |= F_SOFT_P
        if u < 0.0:
            u = 0.0
        if safe:
            if u > prev + step:
                u = prev + step
                flags |= F_SLEW
            elif u < prev - step:
                u = prev - step
                flags |= F_SLEW
            bottom = floor if floor < prev else prev
            if u < bottom:
                u = bottom
        self.flags = flags
        return u
