"""What a status says, declared once (`Status` and its parts, typed), and the one
JSON encoding of it (`jsonsafe`: non-finite floats become null).

The daemon's main thread builds it, in one place (`pamd.daemon.host.snapshot.StatusBuilder`),
a few times a second (never the loop's thread, never per tick; some 50 us); the io
process answers `status` queries from it (`pamd.iohost.answer`), with the live
values of the latest tick record it drained over it (state, measured values,
setpoint, valve command, mode, flags) and what only it knows (`IoStatus`).
"""

from __future__ import annotations

from typing import TypedDict

from pamd.wire.declare.deprecated import DATUM_KEYS, MUSCLE_STATUS_KEYS
from pamd.wire.declare.jsonsafe import JsonObject
from pamd.wire.declare.jsonsafe import jsonsafe as jsonsafe  # the one JSON encoder's


class Trusted(TypedDict):
    pressure: bool
    force: bool
    length: bool


class MuscleLimits(TypedDict):
    max_pressure_bar: float
    max_contraction: float
    max_pretension: float


class Datums(TypedDict):
    """A muscle's datums: the length's (`home`; an absolute sensor has its own) and the
    force's zero (`tare`), as the state directory's calibration.yaml keeps them."""

    has_length_datum: bool
    homed_at: str | None
    tared_at: str | None
    length_offset_mm: float
    force_offset_n: float


class References(TypedDict):
    """Deprecated: `Datums` under the status's old names (`length_referenced` is
    `has_length_datum`), served until `pamd.wire.declare.deprecated.REMOVED_IN`."""

    length_referenced: bool
    homed_at: str | None
    tared_at: str | None
    length_offset_mm: float
    force_offset_n: float


class MuscleStatus(TypedDict):
    """One muscle, as the status says it (units in the names, as in the record)."""

    pressure_bar: float
    setpoint_bar: float
    valve_cmd_bar: float
    force_n: float
    length_mm: float
    contraction: float
    load_kg: float
    safe_pressure_bar: float
    has_length_datum: bool  # the length has its datum (homed, or an absolute sensor)
    mode: str  # pressure, length_force, position
    safe_ramp: bool
    trusted: Trusted
    profile: str | None  # the running profile's shape
    limits: MuscleLimits
    datums: Datums
    model: JsonObject | None  # the inverse model's description (JSON edge)
    adapt: JsonObject  # online adaptation (pamd.loop.control.adapt; JSON edge)
    feedforward: JsonObject  # the model off its data, faded (pamd.loop.control.off_data)
    deadman_left_s: float | None
    # deprecated (pamd.wire.declare.deprecated.MUSCLE_STATUS_KEYS): the old names of
    # `has_length_datum` and `datums`, the same values, until REMOVED_IN
    referenced: bool
    references: References


class SafetyChainStatus(TypedDict):
    closed: bool | None
    supply_bar: float | None
    supply_out: bool
    reset_by: str | None


class ExperimentStatus(TypedDict):
    plan: str
    step: int
    phase: str
    outcome: str | None
    awaiting_operator: str | None
    collection: JsonObject | None  # the collection a remote collect writes into


class RecordingStatus(TypedDict):
    files: list[str]
    failure: JsonObject | None  # why the recording stopped, or None
    lost_records: int  # tick records lost to a full io ring so far (none is normal)


class Status(TypedDict):
    """The daemon's status snapshot (what the main thread builds)."""

    rig_id: str
    state: str
    reason: str
    fault: str | None  # the latched fault's reason, or None
    faults: list[str]
    reload: JsonObject | None  # a config reload's fate (RigController.reload_note)
    safety_chain: SafetyChainStatus | None
    muscles: dict[str, MuscleStatus]
    experiment: ExperimentStatus | None
    config_sha256: str
    config_path: str
    clock: str  # real, virtual, daq
    rate_hz: float
    verbs: list[str]
    recording: RecordingStatus | None
    stopping: str | bool | None
    pamd_version: str
    pid: int
    user: str  # whose daemon it is
    t_wall_s: float
    uptime_s: float


class IoStatus(TypedDict, total=False):
    """What the io process puts into its answer over the snapshot."""

    ok: bool
    error: str
    tick: int
    t_s: float
    snapshot_age_s: float
    timing: JsonObject  # from the tick records (pamd.iohost.answer)
    io: dict[str, int]  # its own counters
    stale: bool
    stale_reasons: list[str]
    live_lag_s: float | None  # how far the live values are behind the loop's newest tick
    lost_records: int  # tick records the loop lost to a full io ring so far, as it says now
    command_nonce: str  # this run's, signed into every command (pamd.wire.credential)
    local_channel: str | None  # the local channel's socket (pamd.wire.local_channel), if it listens
    warnings: list[str]  # what the operator must know: cleartext beyond loopback, ...


def with_old_keys(muscle: JsonObject) -> JsonObject:
    """A muscle's status with the deprecated keys added after the new ones, each the
    value of its new key (in a datums object, its old keys for the new ones)."""
    old_datum_key = {new: old for old, new in DATUM_KEYS.items()}
    out = dict(muscle)
    for old, new in MUSCLE_STATUS_KEYS.items():
        value = muscle[new]
        out[old] = ({old_datum_key.get(k, k): v for k, v in value.items()}
                    if isinstance(value, dict) else value)
    return out


STATUS_FIELDS: tuple[str, ...] = tuple(Status.__annotations__)
MUSCLE_STATUS_FIELDS: tuple[str, ...] = tuple(MuscleStatus.__annotations__)
