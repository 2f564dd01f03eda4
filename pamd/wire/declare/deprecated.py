"""The old names pamd still serves beside their new ones, declared once: what each was,
what it is now and where a user meets it (issue 41: home and tare set datums, never
"references").

Each keeps working until `REMOVED_IN`: a script that names the old tick flag, a client
that reads the status's old keys, a calibration.yaml written before the rename. pamd
itself writes and says only the new names. The fields reference lists them
(`pamd.wire.declare.fields_doc`); the tick flag's alias is `pamd.wire.declare.fields.Flag`'s,
the status's old keys are `pamd.wire.status.MuscleStatus`'s last, and calibration.yaml's
old key is read by `pamd.loop.devices.datum_file`.
"""

from __future__ import annotations

from dataclasses import dataclass

#: the release that drops the old names: the minor release after this one
#: (pamd.wire.version, 0.1.0), which serves both
REMOVED_IN = "0.2.0"


@dataclass(frozen=True)
class OldName:
    """One old name: `old` is served (or read) as `new` until `REMOVED_IN`."""

    old: str
    new: str
    where: str  # where a user meets it, and how the old one still works


#: the tick flag's old names: old -> new (aliases in `Flag`: the same bit)
FLAG_NAMES: dict[str, str] = {"NOT_REFERENCED": "NO_LENGTH_DATUM"}
#: a muscle's status keys: old -> new, served beside the new ones with the same values
MUSCLE_STATUS_KEYS: dict[str, str] = {"referenced": "has_length_datum",
                                      "references": "datums"}
#: a muscle's datum keys (calibration.yaml's muscle entries, the status's `datums`):
#: old -> new; calibration.yaml's old key is read as the new one
DATUM_KEYS: dict[str, str] = {"length_referenced": "has_length_datum"}

OLD_NAMES: tuple[OldName, ...] = (
    OldName("NOT_REFERENCED", "NO_LENGTH_DATUM",
            "the tick flag (bit 7 of `flags`; the bit is unchanged, so every recording "
            "reads the same): `Flag.NOT_REFERENCED` is `Flag.NO_LENGTH_DATUM`, and the "
            "exports' flag tables (`flag_bits`, the CSV sidecar's `flags`) list both"),
    OldName("referenced", "has_length_datum",
            "a muscle's status key (`pamd status --json`, `pamd.connect().status()`, "
            "the Zenoh status answer): served beside the new key, the same value"),
    OldName("references", "datums",
            "a muscle's status object (homed/tared, offsets): served beside the new "
            "one, the same values, its `length_referenced` the new `has_length_datum`"),
    OldName("length_referenced", "has_length_datum",
            "a muscle's key in the state directory's calibration.yaml: a file with the "
            "old key loads (the old key is read as the new one); pamd writes the new"),
)


def check() -> None:
    """The table's own consistency, at import: every old name in one of the maps above
    is described in `OLD_NAMES`, and none twice."""
    mapped = {**FLAG_NAMES, **MUSCLE_STATUS_KEYS, **DATUM_KEYS}
    described = {o.old: o.new for o in OLD_NAMES}
    if described != mapped or len(described) != len(OLD_NAMES):
        raise ValueError(f"old names: described {described}, mapped {mapped}")


check()
