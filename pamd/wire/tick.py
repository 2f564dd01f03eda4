"""The tick record: one fixed-size row of float64 per tick, and the interfaces that
carry it out of the loop (sink) and commands into it (mailbox).

The layout is fixed at start-up from the muscle names: a header of loop fields,
then the same block of fields for each muscle, both declared in the field table
(`pamd.wire.declare.fields`, with the State, Mode and Flag codes). The loop writes into one
reused `array('d')` and hands it to the sink; nothing is allocated per tick. Integers
(tick number, state, flags) are stored exactly as float64.
"""

from __future__ import annotations

import math
from array import array
from collections.abc import Sequence
from typing import Any, Protocol

from pamd.wire.declare import fields

# declared with the field table; imported from here by the rest of pamd
from pamd.wire.declare.fields import Flag as Flag
from pamd.wire.declare.fields import Mode as Mode
from pamd.wire.declare.fields import State as State
from pamd.wire.declare.jsonsafe import JsonObject

#: the loop's fields, then each muscle's block: names from the field table
LOOP_FIELDS: tuple[str, ...] = fields.LOOP_NAMES
MUSCLE_FIELDS: tuple[str, ...] = fields.MUSCLE_NAMES


def loop_offset(name: str) -> int:
    """Offset of loop field `name` in the tick record (at import, never per tick)."""
    if name not in LOOP_FIELDS:
        raise KeyError(f"{name!r} is not a loop field of pamd.wire.declare.fields.LOOP")
    return LOOP_FIELDS.index(name)


def muscle_offset(name: str) -> int:
    """Offset of muscle field `name` in a muscle's block (at import, never per tick)."""
    if name not in MUSCLE_FIELDS:
        raise KeyError(f"{name!r} is not a muscle field of pamd.wire.declare.fields.MUSCLE")
    return MUSCLE_FIELDS.index(name)


class TickLayout:
    """Field offsets of the tick record for a given list of muscles."""

    def __init__(self, muscles: Sequence[str]) -> None:
        self.muscles = tuple(muscles)
        self.size = len(LOOP_FIELDS) + len(MUSCLE_FIELDS) * len(self.muscles)
        self.muscle_base = [
            len(LOOP_FIELDS) + i * len(MUSCLE_FIELDS) for i in range(len(self.muscles))
        ]

    def new_record(self) -> array[float]:
        return array("d", bytes(8 * self.size))

    def muscle_index(self, muscle: int, name: str) -> int:
        return self.muscle_base[muscle] + MUSCLE_FIELDS.index(name)

    def names(self) -> list[str]:
        out = list(LOOP_FIELDS)
        for m in self.muscles:
            out += [f"{m}.{f}" for f in MUSCLE_FIELDS]
        return out

    def as_dict(self, record: Sequence[float]) -> JsonObject:
        """Decode a record (for tests, status and tools; not for the tick)."""
        out: JsonObject = {n: record[i] for i, n in enumerate(LOOP_FIELDS)}
        for k, m in enumerate(self.muscles):
            base = self.muscle_base[k]
            out[m] = {f: record[base + j] for j, f in enumerate(MUSCLE_FIELDS)}
        return out


# Field offsets for the tick path: module constants computed once at import from the
# field table (a name the table does not declare fails the import; no lookup per tick).
I_TICK = loop_offset("tick")
I_T = loop_offset("t_s")
I_WAKE = loop_offset("wake_latency_s")
I_COMPUTE = loop_offset("compute_s")
I_OVERRUNS = loop_offset("overruns")
I_STATE = loop_offset("state")
I_LOST = loop_offset("lost_records")
I_SEGMENT = loop_offset("segment")
I_CHAIN = loop_offset("safety_chain")
I_SUPPLY = loop_offset("supply_bar")
I_HEARTBEAT = loop_offset("heartbeat")
M_PRESSURE = muscle_offset("pressure_bar")
M_FORCE = muscle_offset("force_n")
M_LENGTH = muscle_offset("length_mm")
M_CONTRACTION = muscle_offset("contraction")
M_VELOCITY = muscle_offset("velocity_mm_s")
M_SETPOINT = muscle_offset("setpoint_bar")
M_FEEDFORWARD = muscle_offset("feedforward_bar")
M_PID_P = muscle_offset("pid_p_bar")
M_PID_I = muscle_offset("pid_i_bar")
M_PID_D = muscle_offset("pid_d_bar")
M_VALVE_CMD = muscle_offset("valve_cmd_bar")
M_TARGET_LENGTH = muscle_offset("target_length_mm")
M_TARGET_FORCE = muscle_offset("target_force_n")
M_SAFE_PRESSURE = muscle_offset("safe_pressure_bar")
M_MODE = muscle_offset("mode")
M_FLAGS = muscle_offset("flags")
M_ADAPT_DRIFT = muscle_offset("adapt_drift_bar")
M_ADAPT_STATE = muscle_offset("adapt_state")


class Sink(Protocol):
    """Where tick records and events go. `put` must not block in real time."""

    def put(self, record: array[float]) -> bool:
        """Take one tick record; False if it had to be dropped."""

    def event(self, t_s: float, name: str, data: JsonObject) -> None:
        """A discrete event: supervisor transition, command outcome, ...: its
        `name` declared, with its payload's keys, in pamd.wire.declare.events."""

    def close(self) -> None: ...


class Mailbox(Protocol):
    """Commands into the loop; polled once per tick, never blocks."""

    # Any: a pamd.wire.verbs Command (this leaf is below the verbs layer and cannot name it)
    def poll(self) -> Any | None: ...


NAN = float("nan")


class MuscleTick:
    """What one muscle's stages hand each other within a tick: ros2_control's state and
    command interfaces, one object per muscle, reused every tick (slots: plain stores,
    nothing allocated). Every stage is `update(t, now, dt)` on it (`Stage`); each field
    says which phase writes it. The muscle (`pamd.loop.control.muscle.MuscleController`)
    owns it and runs its stages in three phases: read (its inputs and the checks on
    them), update (the setpoint source and the pressure loop), write (the guards, the
    limiter, the actuation, the adaptation), the rig's safe state decided once between
    every muscle's update and any write (`pamd.loop.control.controller.RigController.tick`)."""

    __slots__ = (
        "state", "flags", "fault", "finding", "last_command_bar", "air_cut",
        "pressure_bar", "force_n", "length_mm", "contraction", "velocity_mm_s",
        "pressure_ok", "length_ok",
        "setpoint_bar", "rate_bar_per_s", "slew_bar_per_s", "flow_bar", "safe",
        "air_hold", "venting", "positioning", "target_length_mm", "target_rate_mm_s",
        "command_bar", "held", "step_bar", "lo_bar", "hi_bar", "floor_bar",
        "position_valves", "ceiling_bar", "valve_floor_bar", "valve_pressure_bar", "vent",
    )

    def __init__(self) -> None:
        # -- read: the muscle, then its inputs (pamd.loop.control.inputs) and the checks on
        # them (pamd.loop.safety.limits.LimitMonitor) -----------------------------------------
        self.state = 0  # the rig's state (pamd.wire.tick.State) this tick's update runs in
        self.flags = 0  # the record's flag bits (pamd.wire.tick.Flag): each stage ORs in its own
        self.fault: str | None = None  # a fault found this tick (read, then write's own)
        self.finding: str | None = None  # a reading no longer trusted (`implausible`)
        self.last_command_bar = NAN  # the command written last tick (NaN: none yet)
        self.air_cut = False  # the air is out or held: no air follows a command
        self.pressure_bar = self.force_n = self.length_mm = self.contraction = NAN
        self.velocity_mm_s = 0.0
        self.pressure_ok = self.length_ok = False  # trusted this tick
        # -- update: the setpoint source (pamd.loop.control.setpoint, length_control); the
        # fixed ones set when the muscle chooses it -------------------------------------
        self.setpoint_bar = NAN  # carried from tick to tick: each source moves it
        self.rate_bar_per_s = 0.0  # the setpoint's rate, for the rate feedforward
        self.slew_bar_per_s = 0.0  # what the limiter holds a safe state's command to
        self.flow_bar = 0.0  # the air the planned motion draws, added to a closed loop
        self.safe = False  # the source is a safe state's (a safe ramp, the air hold)
        self.air_hold = False  # ... the air hold: nothing vents, no pressure acted on
        self.venting = False  # ... a safe ramp at a safe pressure of 0, there: vent
        self.positioning = False  # the valves position the length themselves
        self.target_length_mm = NAN  # ... on this target and its rate
        self.target_rate_mm_s = 0.0
        # -- update: the pressure loop (what control wants); write: the guards, the
        # limiter (what it lets through) ------------------------------------------------
        self.command_bar = NAN
        self.held = False  # held to the safe state's invariants (a safe state, its entry)
        self.step_bar = 0.0  # the slew limit times the period
        self.lo_bar = self.hi_bar = NAN  # the guards' bounds on the command
        self.floor_bar = 0.0  # the limiter's floor while held: the safe pressure
        # -- write: what the actuation acts on (pamd.loop.control.actuation) ------------------
        self.position_valves = False  # the valves position the length this tick
        self.ceiling_bar = NAN  # ... filling no higher (the pressure limit, the guards')
        self.valve_floor_bar = -math.inf  # the valves vent no lower (a safe state)
        self.valve_pressure_bar = NAN  # the pressure the valves act on (NaN: none)
        self.vent = False  # open the exhaust: the tick asks to vent


class Stage(Protocol):
    """One step of a muscle's tick pipeline: reads and writes its `MuscleTick`."""

    def update(self, t: MuscleTick, now: float, dt: float) -> None: ...
