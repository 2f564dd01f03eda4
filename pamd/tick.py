"""The tick record: one fixed-size row of float64 per tick, and the interfaces that
carry it out of the loop (sink) and commands into it (mailbox).

The layout is fixed at start-up from the muscle names: a header of loop fields,
then the same block of fields for each muscle. The loop writes into one reused
`array('d')` and hands it to the sink; nothing is allocated per tick. Integers
(tick number, state, flags) are stored exactly as float64.
"""

from __future__ import annotations

from array import array
from collections.abc import Sequence
from enum import IntEnum, IntFlag
from typing import Any, Protocol

LOOP_FIELDS: tuple[str, ...] = (
    "tick",  # tick number since start, 0-based
    "t_s",  # scheduled tick time since start, s (virtual or monotonic)
    "wake_latency_s",  # how late the loop woke for this tick, s
    "compute_s",  # compute time of the previous tick, s
    "overruns",  # periods skipped since start (cumulative)
    "state",  # supervisor State
    "lost_records",  # records the sink could not take since start (cumulative)
    "segment",  # experiment step + 1 (0 outside a plan): a new recording file each step
    "safety_chain",  # the hardware safety chain: 1 closed, 0 open, NaN no chain input
    "supply_bar",  # the supply pressure (safety_chain.supply; a switch: 0/1), NaN none
    "heartbeat",  # the heartbeat output's level as written this tick (0/1; NaN none)
)

MUSCLE_FIELDS: tuple[str, ...] = (
    "pressure_bar",  # measured pressure
    "force_n",  # measured force
    "length_mm",  # measured length
    "contraction",  # (nominal - length) / nominal, fraction
    "velocity_mm_s",  # filtered d(length)/dt
    "setpoint_bar",  # pressure reference given to the PID
    "feedforward_bar",  # inverse-model (ANFIS) part of the setpoint
    "pid_p_bar",
    "pid_i_bar",
    "pid_d_bar",
    "valve_cmd_bar",  # command written to the regulator after all limits
    "target_length_mm",  # length target (length modes), NaN otherwise
    "target_force_n",  # force target (length_force mode), NaN otherwise
    "safe_pressure_bar",  # present safe pressure for the hanging load
    "mode",  # control Mode
    "flags",  # Flag bits
    "adapt_drift_bar",  # adapted minus trained model output at the last adaptation sample
    "adapt_state",  # AdaptState: 0 off, 1 adapting, 2 paused, 3 frozen, 4 rate-limited
)


class State(IntEnum):
    """Supervisor states."""

    STARTING = 0  # sensors not yet read; nothing written
    IDLE = 1  # holding a pressure, no profile
    RUNNING = 2  # following a profile or remote setpoints
    HOLD = 3  # frozen at the present setpoints
    FAULT = 4  # latched; safe pressure held until reset
    ESTOP = 5  # latched; emergency action taken
    LOAD_CHANGE = 6  # an experiment holds a working pressure while the load is changed


class Mode(IntEnum):
    """Control modes per muscle."""

    PRESSURE = 0
    LENGTH_FORCE = 1
    POSITION = 2


class Flag(IntFlag):
    """Per-muscle condition bits recorded every tick."""

    STALE = 1 << 0  # a signal of this muscle is older than its timeout
    SOFT_LIMIT_PRESSURE = 1 << 1  # command clamped at the pressure limit
    SOFT_LIMIT_CONTRACTION = 1 << 2  # command reduced near the contraction limit
    PRETENSION_LIMIT = 1 << 3  # stretched past the pretension limit: pressure raised
    SLEW_LIMITED = 1 << 4  # setpoint rate limited
    OUTPUT_SATURATED = 1 << 5  # PID output at its limit
    FF_CLIPPED = 1 << 6  # feedforward inputs outside the model's trained range
    NOT_REFERENCED = 1 << 7  # length not referenced (home)
    EXHAUST_OPEN = 1 << 8  # exhaust valve open
    TRACKING = 1 << 9  # pressure outside the tracking band (timer running)


class TickLayout:
    """Field offsets of the tick record for a given list of muscles."""

    def __init__(self, muscles: Sequence[str]) -> None:
        self.muscles = tuple(muscles)
        self.size = len(LOOP_FIELDS) + len(MUSCLE_FIELDS) * len(self.muscles)
        self.muscle_base = [
            len(LOOP_FIELDS) + i * len(MUSCLE_FIELDS) for i in range(len(self.muscles))
        ]

    def new_record(self) -> array:
        return array("d", bytes(8 * self.size))

    def muscle_index(self, muscle: int, name: str) -> int:
        return self.muscle_base[muscle] + MUSCLE_FIELDS.index(name)

    def names(self) -> list[str]:
        out = list(LOOP_FIELDS)
        for m in self.muscles:
            out += [f"{m}.{f}" for f in MUSCLE_FIELDS]
        return out

    def as_dict(self, record: Sequence[float]) -> dict[str, Any]:
        """Decode a record (for tests, status and tools; not for the tick)."""
        out: dict[str, Any] = {n: record[i] for i, n in enumerate(LOOP_FIELDS)}
        for k, m in enumerate(self.muscles):
            base = self.muscle_base[k]
            out[m] = {f: record[base + j] for j, f in enumerate(MUSCLE_FIELDS)}
        return out


# Loop field offsets, for the tick path (no lookups per tick).
(I_TICK, I_T, I_WAKE, I_COMPUTE, I_OVERRUNS, I_STATE, I_LOST, I_SEGMENT, I_CHAIN, I_SUPPLY,
 I_HEARTBEAT) = range(len(LOOP_FIELDS))
(
    M_PRESSURE,
    M_FORCE,
    M_LENGTH,
    M_CONTRACTION,
    M_VELOCITY,
    M_SETPOINT,
    M_FEEDFORWARD,
    M_PID_P,
    M_PID_I,
    M_PID_D,
    M_VALVE,
    M_TARGET_LENGTH,
    M_TARGET_FORCE,
    M_SAFE_PRESSURE,
    M_MODE,
    M_FLAGS,
    M_ADAPT_DRIFT,
    M_ADAPT_STATE,
) = range(len(MUSCLE_FIELDS))


class Sink(Protocol):
    """Where tick records and events go. `put` must not block in real time."""

    def put(self, record: array) -> bool:
        """Take one tick record; False if it had to be dropped."""

    def event(self, t_s: float, kind: str, data: dict[str, Any]) -> None:
        """A discrete event: supervisor transition, command outcome, marker."""

    def close(self) -> None: ...


class Mailbox(Protocol):
    """Commands into the loop; polled once per tick, never blocks."""

    def poll(self) -> Any | None: ...
