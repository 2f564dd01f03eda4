"""What each recorded field is: its unit, its description, and the names behind the
codes (supervisor states, control modes, flag bits), for the Python API, the MATLAB
and CSV exports and the plots. All of it from the field table (pamd.wire.declare.fields)."""

from __future__ import annotations

from pamd.wire.declare import fields as table
from pamd.wire.declare.deprecated import FLAG_NAMES, REMOVED_IN
from pamd.wire.tick import LOOP_FIELDS, MUSCLE_FIELDS, Flag, Mode, State

#: units of names the table does not declare (a column of an older recording): by suffix
_SUFFIXES = (("_mm_s", "mm/s"), ("_bar", "bar"), ("_n", "N"), ("_mm", "mm"), ("_s", "s"),
             ("_kg", "kg"))

#: every field of a muscle's table in the API and the exports, in order
MUSCLE_COLUMNS: tuple[str, ...] = (*table.MUSCLE_MESSAGE_HEAD, *MUSCLE_FIELDS, "state",
                                   "segment")
LOOP_COLUMNS: tuple[str, ...] = LOOP_FIELDS

STATE_NAMES: dict[int, str] = {s.value: s.name for s in State}
MODE_NAMES: dict[int, str] = {m.value: m.name.lower() for m in Mode}
#: every flag's name and bit, a deprecated old name beside its new one (the same bit:
#: `pamd.wire.declare.deprecated`), so that scripts on the exports read either
FLAG_BITS: dict[str, int] = {n: int(f.value) for n, f in Flag.__members__.items()}
FLAG_MEANINGS: dict[str, str] = {
    **{f.name: m for f, m in table.FLAG_MEANINGS.items() if f.name},
    **{old: f"deprecated: {new}'s old name, the same bit (it goes in {REMOVED_IN})"
       for old, new in FLAG_NAMES.items()}}
DESCRIPTIONS: dict[str, str] = {n: f.description for n, f in table.BY_NAME.items()}


def unit_of(name: str) -> str:
    """`pressure_bar` -> "bar", `contraction` -> "1" (a fraction), `state` -> "name"."""
    f = table.BY_NAME.get(name)
    if f is not None:
        return f.unit
    for suffix, unit in _SUFFIXES:
        if name.endswith(suffix):
            return unit
    return ""


def state_name(code: float) -> str:
    return STATE_NAMES.get(int(code), f"?{code:g}") if code == code else ""


def mode_name(code: float) -> str:
    return MODE_NAMES.get(int(code), f"?{code:g}") if code == code else ""
