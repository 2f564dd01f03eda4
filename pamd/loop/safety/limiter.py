"""The limiter: the supervisor's invariants on one muscle's valve command, applied
last, after the setpoint, the PID and every guard. Nothing downstream of it
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
invariants from the command written last, whichever signal failed, and so is the
tick in which any muscle of the rig found one: every muscle's write of that tick
(`pamd.loop.control.controller.RigController.tick`). So the entry never takes the command
below min(safe pressure, the command at entry) nor faster than the safe slew
(`safety.safe_slew_bar_per_s`). Every path that moves the rig (`pamd run`, `pamd
tune`, `pamd collect`, remote commands and collections) reaches the valves through
this one limiter.

The one exception is an ESTOP whose action is `vent`, honoured only where the safe
pressure is 0 (the load needs no pressure): the command drops to 0 at once and
the exhaust opens (the caller passes a floor of 0 and an unlimited step).
"""

from __future__ import annotations

import math

from pamd.wire.tick import Flag, MuscleTick

F_SOFT_P, F_SLEW = int(Flag.SOFT_LIMIT_PRESSURE), int(Flag.SLEW_LIMITED)
F_SOFT_C, F_PRETENSION = int(Flag.SOFT_LIMIT_CONTRACTION), int(Flag.PRETENSION_LIMIT)

HELD_BACK_BAR = 0.005
"""A command clamped at the pressure limit holds the setpoint back only where the
setpoint itself asks for more than the command by this much; the top of a profile that
reaches the limit, where only the PID's correction is trimmed, is not held back."""


def held_back(flags: int, setpoint_bar: float, command_bar: float) -> bool:
    """Whether a limit or guard held the setpoint back this tick (what the summary
    counts and a `soft_limit` event reports): a contraction or pretension guard, or
    the pressure limit below the setpoint."""
    return bool(flags & (F_SOFT_C | F_PRETENSION)) or (
        bool(flags & F_SOFT_P) and setpoint_bar > command_bar + HELD_BACK_BAR)


class Limiter:
    """Applies the invariants to the muscle's command (`update`, the write's stage after
    the guards); `flags` holds the bits of the last one."""

    def __init__(self, max_pressure_bar: float = math.inf) -> None:
        self.flags = 0
        self.max_pressure_bar = max_pressure_bar  # the muscle's (set-up and IDLE reloads)

    def update(self, t: MuscleTick, now: float, dt: float) -> None:
        """`t.command_bar` (what control wants) becomes the command to write: within
        the guards' bounds (`t.lo_bar`, `t.hi_bar`: restoring direction only), the
        pressure limit and 0; and while `t.held` (a safe state or its entry), within
        `t.step_bar` (the slew limit times the period) of the command written last
        (`t.last_command_bar`), never below min(`t.floor_bar`, that command)."""
        u = t.command_bar
        flags = 0
        hi = t.hi_bar
        if u > hi:
            u = hi
        lo = t.lo_bar
        if u < lo:
            u = lo
        max_p = self.max_pressure_bar
        if u > max_p:
            u = max_p
            flags = F_SOFT_P
        if u < 0.0:
            u = 0.0
        if t.held:
            prev, step = t.last_command_bar, t.step_bar
            if u > prev + step:
                u = prev + step
                flags |= F_SLEW
            elif u < prev - step:
                u = prev - step
                flags |= F_SLEW
            floor = t.floor_bar
            bottom = floor if floor < prev else prev
            if u < bottom:
                u = bottom
        self.flags = flags
        t.flags |= flags
        t.command_bar = u
