"""The `custom` muscle type: a lab's own muscle, from the map it measured and the
ratings its config states (`muscles[].custom`: nothing about it is assumed).

The table is read by `pamd.config.muscle_types` through the reader `pamd train` uses
(CSV or MAT, units converted), checked by `pamd.muscle_type.mapcheck` against the
muscle's limits, and handed here as rows.
"""

from __future__ import annotations

import hashlib
import struct
from collections.abc import Sequence

from pamd.muscle_type.definition import MuscleType
from pamd.muscle_type.forces import ForceMap
from pamd.muscle_type.mapcheck import MapPoint

NAME = "custom"


def custom_type(points: Sequence[MapPoint], map_file: str, *, max_pressure_bar: float,
                max_contraction: float, max_pretension: float, max_load_kg: float,
                theoretical_force_n: float, inner_diameter_mm: float) -> MuscleType:
    """A custom type from its checked map rows and the config's ratings."""
    return MuscleType(
        name=NAME, max_pressure_bar=max_pressure_bar, max_contraction=max_contraction,
        max_pretension=max_pretension, max_load_kg=max_load_kg,
        theoretical_force_n=theoretical_force_n, inner_diameter_mm=inner_diameter_mm,
        force_map=ForceMap([(q.pressure_bar, q.contraction, q.force_n) for q in points]),
        source=f"the lab's map {map_file} and the config's ratings", map_file=map_file,
        map_sha256=map_digest(points))


def map_digest(points: Sequence[MapPoint]) -> str:
    """The SHA-256 of a map's rows as read (each pressure, contraction and force as a
    float64): the same table gives the same digest, any changed value another."""
    h = hashlib.sha256()
    for q in points:
        h.update(struct.pack("<3d", q.pressure_bar, q.contraction, q.force_n))
    return h.hexdigest()
