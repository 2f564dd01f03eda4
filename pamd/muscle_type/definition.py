"""What a muscle type is: its ratings, its geometry and its static force map.

Every figure that keeps a load safe comes from here: the pressure, contraction,
pretension, load and force ratings bound the config's limits and its checks; the map
F(pressure, contraction) gives the safe pressure, the plausibility checks' physics,
the plans' contraction checks and the simulated plant's muscle. A datasheet type
(`pamd.muscle_type.dmsp20`, `dmsp40`) states Festo's published figures; a `custom`
type's come from the lab's config and measured table (`pamd.config.muscle_types`).
"""

from __future__ import annotations

from dataclasses import dataclass

from pamd.muscle_type.forces import ForceMap, ForceModel, SmoothForceFit

#: the force models a muscle may name (`muscles[].force_model`): the map itself, or a
#: smooth closed-form fit of it where its type has one
FORCE_MODELS = ("map", "fit")


@dataclass(frozen=True, eq=False)
class MuscleType:
    """One muscle type's ratings (the most it may see), geometry and force map.

    Compared and hashed by identity: a datasheet type is one object for the process
    (`pamd.muscle_type.registry`), so what is derived from it once is kept."""

    name: str  # `muscles[].type`
    max_pressure_bar: float
    max_contraction: float  # of the nominal length, a fraction
    max_pretension: float  # stretch beyond the nominal length, a positive fraction
    max_load_kg: float  # the largest hanging load
    theoretical_force_n: float  # the rated pull (Festo: at 6 bar and 0 % contraction)
    inner_diameter_mm: float
    force_map: ForceMap
    #: the nominal lengths the type is made in (None: not stated)
    nominal_length_range_mm: tuple[float, float] | None = None
    #: a smooth fit of the map (`force_model: fit`), where one has been derived
    force_fit: SmoothForceFit | None = None
    #: where its figures come from (said in errors and by `pamd check-config`)
    source: str = ""
    #: a custom type's measured table (absolute path), None for a datasheet type
    map_file: str | None = None
    #: a custom type's map as read (its rows, units converted), hashed: what a reload
    #: compares, since the table may change on disk while the config's text does not
    map_sha256: str | None = None

    def force_model(self, name: str = "map") -> ForceModel:
        """The force model `name`d ('map' or 'fit') of this type; ValueError when the
        type has no fit (the loader refuses that config with the reason)."""
        if name == "map":
            return self.force_map
        if name == "fit":
            if self.force_fit is None:
                raise ValueError(f"the {self.name} type has no smooth fit of its map; use "
                                 "force_model: map")
            return self.force_fit
        raise ValueError(f"unknown force model {name!r}; use one of {', '.join(FORCE_MODELS)}")

    def stops(self) -> tuple[float, float]:
        """Where a simulated rig's hard stops sit by default (contraction fractions):
        1 % past the rated pretension (the catch under the load) and at the rated
        contraction (the braid's end)."""
        return -(self.max_pretension + 0.01), self.max_contraction
