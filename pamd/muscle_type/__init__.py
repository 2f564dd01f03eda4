"""Muscle types: each one's ratings, geometry and static force map F(pressure,
contraction), and what is solved on a map.

* `forces`: the force models (`ForceMap`, the DMSP-20's `SmoothForceFit`), the
  equilibrium contraction under a hanging load and the pressure for a force;
* `definition`: `MuscleType`, a type's ratings, geometry and map;
* `dmsp20`, `dmsp40`: Festo's datasheet types; `custom`: a lab's own muscle from its
  measured map and its config's ratings;
* `registry`: the types by the name `muscles[].type` gives;
* `mapcheck`: what a map must be before a muscle uses it (finite, enough points,
  monotone as the physics says, reaching the configured limits).

A muscle's type is resolved with its config (`pamd.config.LoadedConfig.muscle_type`);
everything that keeps its load safe reads it from there.
"""

from __future__ import annotations

from pamd.muscle_type.definition import FORCE_MODELS, MuscleType
from pamd.muscle_type.forces import (
    GRAVITY_M_S2,
    ForceMap,
    ForceModel,
    SmoothForceFit,
    equilibrium_contraction,
    pressure_for_force,
)
from pamd.muscle_type.mapcheck import MapBox, MapPoint, check_map
from pamd.muscle_type.registry import DEFAULT_TYPE, TYPE_NAMES, datasheet_type

__all__ = [
    "DEFAULT_TYPE", "FORCE_MODELS", "GRAVITY_M_S2", "TYPE_NAMES", "ForceMap", "ForceModel",
    "MapBox", "MapPoint", "MuscleType", "SmoothForceFit", "check_map", "datasheet_type",
    "equilibrium_contraction", "force_model", "pressure_for_force",
]


def force_model(name: str = "map") -> ForceModel:
    """The DMSP-20's force model by name, 'map' (its datasheet map) or 'fit' (the smooth
    fit): the reference rig's, for benches and tests that study that muscle. A rig's
    muscle takes its own type's (`MuscleType.force_model`)."""
    return datasheet_type(DEFAULT_TYPE).force_model(name)
