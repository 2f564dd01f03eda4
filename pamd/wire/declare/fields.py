"""The field table: every value pamd records or publishes per tick, declared once.

A tick record is a row of float64: the loop's fields (`LOOP`), then the same block of
fields for each muscle (`MUSCLE`). Each field has its name (units in the name where
the unit is a physical one), its unit, the ROS 2 primitive type it is recorded as in
MCAP (integers are stored exactly as float64 in the tick record and recorded as the
integer type), a description, and, for codes and bit fields, the enum that names
them (`State`, `Mode`, `Flag` with `FLAG_MEANINGS`). `plot` places a field on a panel
of the Foxglove layout.

Adding a recorded value: a `Field` here (in the record's order) and the stage that
writes it (its index: `pamd.wire.tick.muscle_offset(name)`, a module constant computed at
import). The schemas, exports, layout and docs follow.
"""

from __future__ import annotations

import builtins
from dataclasses import dataclass
from enum import IntEnum, IntFlag

from pamd.wire.declare import deprecated

#: the ROS 2 primitive types a field may be recorded as
TYPES = ("float64", "uint8", "uint16", "uint32", "uint64")


class State(IntEnum):
    """Supervisor states."""

    STARTING = 0  # sensors not yet read; nothing written
    IDLE = 1  # holding a pressure, no profile
    RUNNING = 2  # following a profile or remote setpoints
    HOLD = 3  # frozen at the present setpoints
    FAULT = 4  # latched; safe pressure held until reset
    ESTOP = 5  # latched; emergency action taken
    LOAD_CHANGE = 6  # an experiment holds a working pressure while the load is changed


STATE_MEANINGS: dict[State, str] = {
    State.STARTING: "sensors not yet read; nothing written",
    State.IDLE: "holding a pressure, no profile",
    State.RUNNING: "following a profile or remote setpoints",
    State.HOLD: "frozen at the present setpoints",
    State.FAULT: "latched; safe pressure held until reset",
    State.ESTOP: "latched; emergency action taken",
    State.LOAD_CHANGE: "an experiment holds a working pressure while the load is changed",
}


class Mode(IntEnum):
    """Control modes per muscle."""

    PRESSURE = 0
    LENGTH_FORCE = 1
    POSITION = 2


MODE_MEANINGS: dict[Mode, str] = {
    Mode.PRESSURE: "a pressure setpoint, PID pressure loop",
    Mode.LENGTH_FORCE: "length and force targets -> inverse model -> pressure setpoint",
    Mode.POSITION: "a length target: the model on the measured force and an outer "
                   "position PID",
}


class Flag(IntFlag):
    """Per-muscle condition bits recorded every tick (meanings: `FLAG_MEANINGS`)."""

    STALE = 1 << 0
    SOFT_LIMIT_PRESSURE = 1 << 1
    SOFT_LIMIT_CONTRACTION = 1 << 2
    PRETENSION_LIMIT = 1 << 3
    SLEW_LIMITED = 1 << 4
    OUTPUT_SATURATED = 1 << 5
    FF_CLIPPED = 1 << 6
    NO_LENGTH_DATUM = 1 << 7
    EXHAUST_OPEN = 1 << 8
    TRACKING = 1 << 9
    INFLATE_OPEN = 1 << 10
    FF_OFF_DATA = 1 << 11
    FF_FADED = 1 << 12
    FF_OSCILLATING = 1 << 13
    #: deprecated: NO_LENGTH_DATUM's old name, the same bit (an alias, so
    #: `Flag.NOT_REFERENCED is Flag.NO_LENGTH_DATUM`; iterating `Flag` gives the new one
    #: only), kept for old scripts until `pamd.wire.declare.deprecated.REMOVED_IN`
    NOT_REFERENCED = NO_LENGTH_DATUM


FLAG_MEANINGS: dict[Flag, str] = {
    Flag.STALE: "a signal of this muscle is older than its timeout",
    Flag.SOFT_LIMIT_PRESSURE: "command clamped at the pressure limit",
    Flag.SOFT_LIMIT_CONTRACTION: "command reduced near the contraction limit",
    Flag.PRETENSION_LIMIT: "stretched past the pretension limit: pressure raised",
    Flag.SLEW_LIMITED: "setpoint rate limited",
    Flag.OUTPUT_SATURATED: "PID output at its limit",
    Flag.FF_CLIPPED: "feedforward inputs outside the model's trained range",
    Flag.NO_LENGTH_DATUM: "the length has no datum yet (home)",
    Flag.EXHAUST_OPEN: "exhaust valve open",
    Flag.TRACKING: "pressure outside the tracking band (timer running)",
    Flag.INFLATE_OPEN: "inflate valve open (on/off valves)",
    Flag.FF_OFF_DATA: "feedforward inputs outside the model's training domain (a force "
                      "beyond its trained loads, or a length, velocity or pressure not seen "
                      "at that force)",
    Flag.FF_FADED: "feedforward faded (partly or wholly) to the position PID alone",
    Flag.FF_OSCILLATING: "feedforward oscillating against the pressure loop",
}

#: The valve flags that, on on/off valves (`actuation: onoff`), mark the PWM's own
#: pulses: the control itself, a few ms in each period, inflate and exhaust alike (the
#: pressure sensor reads the muscle at every sample either way). With a regulator the
#: exhaust is the exhaust valve, which vents past the regulator: there EXHAUST_OPEN says
#: the pressure is the vent's, and training and adaptation drop those samples.
PWM_VALVE_FLAGS = Flag.EXHAUST_OPEN | Flag.INFLATE_OPEN

#: `adapt_state`'s codes (pamd.loop.control.adapt.AdaptState holds the same values)
ADAPT_STATES: dict[int, str] = {0: "off", 1: "adapting", 2: "paused", 3: "frozen",
                                4: "rate-limited"}


@dataclass(frozen=True)
class Field:
    """One recorded value."""

    name: str
    unit: str  # "bar", "N", "mm", "mm/s", "s", "1" (a fraction), or what the count counts
    type: str  # ROS 2 primitive type in the MCAP message (TYPES)
    description: str
    codes: dict[int, str] | None = None  # names of the values of a code field
    bits: builtins.type[IntFlag] | None = None  # the flag enum of a bit field
    plot: str = ""  # the Foxglove layout's panel that shows it ("" none)
    label: str = ""  # its legend there


def _codes(enum: type[IntEnum], lower: bool = False) -> dict[int, str]:
    return {int(e.value): e.name.lower() if lower else e.name for e in enum}


LOOP: tuple[Field, ...] = (
    Field("tick", "tick", "uint64", "tick number since the run start, 0-based"),
    Field("t_s", "s", "float64", "scheduled tick time since the run start (virtual or "
          "monotonic clock)"),
    Field("wake_latency_s", "s", "float64", "how late the loop woke for this tick"),
    Field("compute_s", "s", "float64", "compute time of the previous tick"),
    Field("overruns", "periods", "uint64", "periods skipped since start (cumulative)"),
    Field("state", "name", "uint8", "supervisor state", codes=_codes(State)),
    Field("lost_records", "records", "uint64", "records the sink could not take since "
          "start (cumulative)"),
    Field("segment", "step + 1", "uint16", "experiment step + 1 (0 outside a plan): a new "
          "recording file each step"),
    Field("safety_chain", "0/1", "float64", "the hardware safety chain: 1 closed, 0 open, "
          "NaN no chain input"),
    Field("supply_bar", "bar", "float64", "the supply pressure (safety_chain.supply; a "
          "switch reads 0/1), NaN none"),
    Field("heartbeat", "0/1", "float64", "the heartbeat output's level as written this "
          "tick, NaN none"),
)

MUSCLE: tuple[Field, ...] = (
    Field("pressure_bar", "bar", "float64", "measured pressure", plot="pressure",
          label="pressure"),
    Field("force_n", "N", "float64", "measured force", plot="force", label="force"),
    Field("length_mm", "mm", "float64", "measured length", plot="length", label="length"),
    Field("contraction", "1", "float64", "(nominal - length) / nominal"),
    Field("velocity_mm_s", "mm/s", "float64", "filtered d(length)/dt"),
    Field("setpoint_bar", "bar", "float64", "pressure setpoint given to the PID (NaN: "
          "on/off valves in position mode have none)", plot="pressure", label="setpoint"),
    Field("feedforward_bar", "bar", "float64", "inverse-model (ANFIS) part of the setpoint "
          "(faded off the model's training domain: FF_FADED)"),
    Field("pid_p_bar", "bar", "float64", "PID proportional term"),
    Field("pid_i_bar", "bar", "float64", "PID integral term"),
    Field("pid_d_bar", "bar", "float64", "PID derivative term"),
    Field("valve_cmd_bar", "bar", "float64", "command written to the regulator after all "
          "limits", plot="pressure", label="valve command"),
    Field("target_length_mm", "mm", "float64", "length target (NaN outside length modes)",
          plot="length", label="target"),
    Field("target_force_n", "N", "float64", "force target (NaN outside length_force mode)",
          plot="force", label="force target"),
    Field("safe_pressure_bar", "bar", "float64", "safe pressure for the hanging load"),
    Field("mode", "name", "uint8", "control mode", codes=_codes(Mode, lower=True)),
    Field("flags", "bits", "uint32", "condition bits (see the flag table)", bits=Flag),
    Field("adapt_drift_bar", "bar", "float64", "adapted minus trained model output at the "
          "last adaptation sample"),
    Field("adapt_state", "code", "uint8", "the model's online adaptation",
          codes=ADAPT_STATES),
)

#: the loop fields a muscle's message (MCAP topic /pamd/<rig>/state/<muscle>) starts with
MUSCLE_MESSAGE_HEAD: tuple[str, ...] = ("tick", "t_s")

#: columns the exports add to what was recorded
DERIVED: tuple[Field, ...] = (
    Field("load_kg", "kg", "float64", "hanging load of the file's step (or the config's)"),
    Field("file", "index", "float64", "index of the file the tick came from (0-based)"),
)

LOOP_NAMES: tuple[str, ...] = tuple(f.name for f in LOOP)
MUSCLE_NAMES: tuple[str, ...] = tuple(f.name for f in MUSCLE)
BY_NAME: dict[str, Field] = {f.name: f for f in (*LOOP, *MUSCLE, *DERIVED)}


def muscle_message() -> tuple[Field, ...]:
    """The fields of a muscle's recorded message, in order: tick, t_s, then MUSCLE."""
    return (*(BY_NAME[n] for n in MUSCLE_MESSAGE_HEAD), *MUSCLE)


def check_table() -> None:
    """The table's own consistency, at import (a wrong table is a bug, found at once)."""
    names = [f.name for f in (*LOOP, *MUSCLE, *DERIVED)]
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:
        raise ValueError(f"fields declared twice: {twice}")
    for f in BY_NAME.values():
        if f.type not in TYPES:
            raise ValueError(f"field {f.name}: type {f.type!r} is not one of {TYPES}")
        if not f.unit or not f.description:
            raise ValueError(f"field {f.name}: a unit and a description are required")
    for meanings, enum in ((FLAG_MEANINGS, Flag), (STATE_MEANINGS, State),
                           (MODE_MEANINGS, Mode)):
        if set(meanings) != set(enum):
            raise ValueError(f"{enum.__name__}: every member needs a meaning")
    for old, new in deprecated.FLAG_NAMES.items():
        if Flag.__members__.get(old) is not Flag[new]:
            raise ValueError(f"Flag.{old}: the deprecated alias of Flag.{new} is missing")


check_table()
