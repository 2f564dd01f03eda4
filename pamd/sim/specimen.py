"""The simulated muscle itself: the force model its plant pulls with, its inner diameter
(the air volume of 'flow' pneumatics) and its hard stops, from its `type`.

A datasheet type (dmsp20, dmsp40) gives all three; a custom muscle's map is the table
its options name (read and checked by `drivers/sim.py` when the driver is built, never
in the tick) and its diameter and stops are its options' (`check_options` refuses a
custom muscle without them).
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import dataclass, replace

from pamd.muscle_type import DEFAULT_TYPE, ForceModel, MuscleType, datasheet_type
from pamd.muscle_type.custom import NAME as CUSTOM
from pamd.sim.options import SimMuscleOptions, SimOptions, stops

#: a simulated muscle's input channels are NAME.<input>
MUSCLE_INPUTS = ("pressure", "force", "length")


@dataclass(frozen=True)
class Specimen:
    """What one simulated muscle is (see the module's doc)."""

    type_name: str
    model: ForceModel
    inner_diameter_mm: float
    stop_stretch_contraction: float
    stop_contraction: float


def specimen(o: SimMuscleOptions, custom_map: ForceModel | None = None) -> Specimen:
    """The muscle `o` simulates; `custom_map`: a custom muscle's map, read from its
    `map_file`. ValueError where the options do not say enough (`check_options` names
    what is missing first)."""
    name = o.type or DEFAULT_TYPE
    lo, hi = stops(o)
    if name == CUSTOM:
        if custom_map is None or o.inner_diameter_mm is None or lo is None or hi is None:
            raise ValueError(f"simulated muscle {o.name!r}: a custom muscle needs its map, "
                             "inner_diameter_mm and both stops")
        return Specimen(name, custom_map, o.inner_diameter_mm, lo, hi)
    t = datasheet_type(name)
    assert lo is not None and hi is not None  # a datasheet type's stops
    return Specimen(name, t.force_model(o.force_model), t.inner_diameter_mm, lo, hi)


def bind_types(options: SimOptions, types: Mapping[str, MuscleType],
               base_dir: str) -> SimOptions:
    """The options with each simulated muscle's type settled: one with no `type` takes
    the type of the rig muscle reading its channels (`types`: channel name -> that
    muscle's type; dmsp20 where none does), a custom one with its map, inner diameter and
    stops (its ratings' pretension and contraction) where the options leave them open; a
    map file is made absolute (relative to the config file's directory, `base_dir`)."""
    muscles = []
    for m in options.muscles:
        t = next((types[c] for c in (f"{m.name}.{s}" for s in MUSCLE_INPUTS) if c in types),
                 None)
        if m.type is None and t is not None:
            m = _as_type(m, t)
        if m.map_file is not None:
            m = replace(m, map_file=os.path.join(base_dir, os.path.expanduser(m.map_file)))
        muscles.append(m)
    return replace(options, muscles=tuple(muscles))


def _as_type(m: SimMuscleOptions, t: MuscleType) -> SimMuscleOptions:
    """`m` as a muscle of type `t` (a rig muscle's): a custom one with what the plant
    needs of it, given where the options leave it open."""
    if t.map_file is None:
        return replace(m, type=t.name)
    lo, hi = t.stops()
    return replace(m, type=t.name, map_file=t.map_file,
                   inner_diameter_mm=m.inner_diameter_mm or t.inner_diameter_mm,
                   stop_stretch_contraction=(lo if m.stop_stretch_contraction is None
                                             else m.stop_stretch_contraction),
                   stop_contraction=hi if m.stop_contraction is None else m.stop_contraction)
