"""The muscle types pamd knows, by the name `muscles[].type` gives.

A datasheet type is a module (its ratings from the manufacturer's published figures,
its map digitised into `pamd/data`) and one `register` line here; `custom` is the
lab's own (`pamd.muscle_type.custom`, built from its config). Another Festo size is
added only with figures and a map that can be cited.
"""

from __future__ import annotations

from collections.abc import Callable

from pamd.muscle_type import custom, dmsp20, dmsp40
from pamd.muscle_type.definition import MuscleType

#: name -> the datasheet type (made once, on first use)
DATASHEET_TYPES: dict[str, Callable[[], MuscleType]] = {}


def register(name: str, make: Callable[[], MuscleType]) -> None:
    if name in DATASHEET_TYPES or name == custom.NAME:
        raise ValueError(f"muscle type {name!r} registered twice")
    DATASHEET_TYPES[name] = make


register(dmsp20.NAME, dmsp20.muscle_type)
register(dmsp40.NAME, dmsp40.muscle_type)

#: every name `muscles[].type` may give
TYPE_NAMES: tuple[str, ...] = (*DATASHEET_TYPES, custom.NAME)
#: the type of a muscle whose config names none (the reference rig's)
DEFAULT_TYPE = dmsp20.NAME


def datasheet_type(name: str) -> MuscleType:
    """A datasheet type by name; KeyError names the ones there are."""
    if name not in DATASHEET_TYPES:
        raise KeyError(f"no datasheet muscle type {name!r} (there are "
                       f"{', '.join(DATASHEET_TYPES)}; a lab's own muscle is type custom)")
    return DATASHEET_TYPES[name]()
