"""Festo DMSP-20 (inner diameter 20 mm): the datasheet's figures and force map.

Ratings as seed 002's Table 3 and the reference (`../shared/reference/rig-physics.md`)
give Festo's: 0-6 bar, at most 25 % contraction and 4 % pretension, theoretical force
1500 N, at most 80 kg additional load, nominal lengths 60 to 9000 mm. The map is the
datasheet's, digitised (`pamd/data/dmsp20_force_map.csv`, 58 points on seven curves
at 0..6 bar); the smooth fit is the reference's (RMS 6.5 N over those points).
"""

from __future__ import annotations

import functools

from pamd.muscle_type.definition import MuscleType
from pamd.muscle_type.forces import ForceMap, SmoothForceFit, package_map_points

NAME = "dmsp20"


@functools.cache
def muscle_type() -> MuscleType:
    """The DMSP-20 (one object per process: its map is read once)."""
    return MuscleType(
        name=NAME, max_pressure_bar=6.0, max_contraction=0.25, max_pretension=0.04,
        max_load_kg=80.0, theoretical_force_n=1500.0, inner_diameter_mm=20.0,
        force_map=ForceMap(package_map_points("dmsp20_force_map.csv")),
        nominal_length_range_mm=(60.0, 9000.0), force_fit=SmoothForceFit(),
        source="Festo DMSP-20 datasheet (seed 002 Table 3; pamd/data/dmsp20_force_map.csv)")
