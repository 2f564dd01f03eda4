"""The rig's safe state, over all its muscles (one job of the rig controller,
`pamd.loop.control.controller`): the coordinated entry into it, whether the rig has reached it,
and whether the rig is at rest (where a reload's limits and loads apply)."""

from __future__ import annotations

from collections.abc import Sequence

from pamd.loop.control.muscle import MuscleController
from pamd.wire.tick import State

#: In FAULT or ESTOP, the valve command is at the safe pressure within this (bar).
SAFE_CMD_BAND_BAR = 1e-3

#: A setpoint is at its safe pressure within this (bar).
SAFE_SETPOINT_BAND_BAR = 1e-6


def pace_safe_entry(muscles: Sequence[MuscleController], estop: bool) -> None:
    """The rig's coordinated entry into its safe state: every muscle's ramp to its
    safe pressure lasts as long as the longest one at its own slew limit (each never
    faster than its slew limit), so the muscles arrive together and an antagonistic
    pair does not slam its joint by one muscle ramping alone. Called when a fault or
    an emergency stop latches, on a stop (`go_safe`) and at start-up for the muscles
    that start outside their limits."""
    duration_s = max((m.safe_entry_s(estop) for m in muscles), default=0.0)
    for m in muscles:
        m.pace_safe_entry(duration_s, estop)


def at_safe_state(muscles: Sequence[MuscleController], latched: bool) -> bool:
    """True when every started muscle's setpoint has reached its safe pressure (or
    nothing was ever written); when `latched` (FAULT or ESTOP, where the pressure loop
    is open), its valve command too (it follows the setpoint at the slew limit from
    the command written when the fault struck). A muscle holding its air after the
    safety chain opened or the supply was lost is at its safe state where it holds."""
    return all(not m.started or (latched and m.holding_air) or (
        abs(m.setpoint_bar - m.safe_pressure_bar) <= SAFE_SETPOINT_BAND_BAR and (
            not latched or _command_at_safe(m)))
               for m in muscles)


def _command_at_safe(m: MuscleController) -> bool:
    """The muscle's valve command at its safe pressure, within SAFE_CMD_BAND_BAR."""
    return abs(m.valve_cmd_bar - m.safe_pressure_bar) <= SAFE_CMD_BAND_BAR


def commands_at_safe(muscles: Sequence[MuscleController]) -> bool:
    """Every started muscle's valve command at its safe pressure (within
    SAFE_CMD_BAND_BAR), or its air held. The end of a stop's settle: once a stop's ramp
    has brought the setpoint to the safe pressure, the pressure loop still corrects
    the pressure lagging behind it (the air takes its time to leave the muscle), and a
    device that holds its last command (a regulator) would go on holding that
    correction after the loop ends. The loop waits for the command to reach the safe
    pressure, at most `safety.tracking_time_s` (`pamd.loop.loop.Loop`): where the
    pressure loop must hold a correction to keep the pressure there (a regulator's
    offset), that correction is what the safe state needs."""
    return all(not m.started or m.holding_air or _command_at_safe(m) for m in muscles)


def at_rest(muscles: Sequence[MuscleController], state: State) -> bool:
    """IDLE with nothing moving: no profile, and every ramp to the safe state (a stop,
    a deadman, a start-up outside the limits) has reached its safe pressure."""
    return state == State.IDLE and all(
        not m.started or (m.profile is None and (
            not m.in_safe_ramp
            or abs(m.setpoint_bar - m.safe_pressure_bar) <= SAFE_SETPOINT_BAND_BAR))
        for m in muscles)


def rest_text(muscles: Sequence[MuscleController], state: State) -> str:
    """Why the rig is not at rest (for a deferred reload's note)."""
    if state != State.IDLE:
        return state.name
    moving = [m.name for m in muscles if m.started and m.profile is not None]
    if moving:
        return f"IDLE, {', '.join(moving)} following a profile"
    return "IDLE, ramping to the safe state"
