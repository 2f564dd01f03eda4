"""Festo DMSP-40 (inner diameter 40 mm): the datasheet's figures and force map.

Ratings as seed 002's Table 3 gives Festo's: 0-6 bar, at most 25 % contraction and 5 %
pretension, theoretical force 6000 N, at most 250 kg additional load, nominal lengths
120 to 9000 mm. The map is the datasheet's, digitised the same way as the DMSP-20's
(`pamd/data/dmsp40_force_map.csv`, 61 points on seven curves at 0..6 bar, -5 to 25 %
contraction; the reference's copy). No smooth fit has been derived for it: its
`force_model` is the map.
"""

from __future__ import annotations

import functools

from pamd.muscle_type.definition import MuscleType
from pamd.muscle_type.forces import ForceMap, package_map_points

NAME = "dmsp40"


@functools.cache
def muscle_type() -> MuscleType:
    """The DMSP-40 (one object per process: its map is read once)."""
    return MuscleType(
        name=NAME, max_pressure_bar=6.0, max_contraction=0.25, max_pretension=0.05,
        max_load_kg=250.0, theoretical_force_n=6000.0, inner_diameter_mm=40.0,
        force_map=ForceMap(package_map_points("dmsp40_force_map.csv")),
        nominal_length_range_mm=(120.0, 9000.0),
        source="Festo DMSP-40 datasheet (seed 002 Table 3; pamd/data/dmsp40_force_map.csv)")
