"""Plausibility thresholds that can never fire, or fire on a healthy rig, are refused at
load with the reason (`safety.plausibility`; the checks and their physics are in
`pamd.loop.safety.plausibility`). Per muscle, against its limits and its type's ratings:

* an impossible-length range (`min_contraction` .. `max_contraction`) that does not
  contain the muscle's own hard limits faults a healthy muscle at its limit (always);
* a length or pressure jump allowance as large as the muscle's whole travel or
  pressure range: no jump can exceed it (never);
* a frozen-length pressure change above the pressure limit (never);
* a frozen-force band whose friction swing (twice it) reaches the muscle's rated force:
  no force map moves that far (never);
* a zero-force share of 0 (never: no reading is below 0 % of the weight) or so close to
  1 that a healthy load cell, reading the weight give or take friction and the load's
  acceleration, is below it (always: at most `MAX_ZERO_FRACTION`);
* a smallest load for the zero-force check above every muscle's rated load (never).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Protocol

from pamd.config.safety_schema import PlausibilityConfig
from pamd.config.schema import MuscleConfig, RigConfig
from pamd.muscle_type import MuscleType
from pamd.wire.declare.jsonsafe import JsonValue
from pamd.wire.schema.engine import Context, line_of

#: A healthy load cell under a hanging load reads the weight give or take friction and
#: the load's acceleration (tens of percent while it moves): the zero-force check's
#: share must stay well below that.
MAX_ZERO_FRACTION = 0.5


class _Limits(Protocol):
    """A muscle's resolved limits (`pamd.config.loader.MuscleLimitsResolved`)."""

    @property
    def max_pressure_bar(self) -> float: ...

    @property
    def hard_max_pressure_bar(self) -> float: ...

    @property
    def hard_max_contraction(self) -> float: ...

    @property
    def hard_max_pretension(self) -> float: ...


#: refuse(key, expected, found): an issue at `safety.plausibility.<key>`
_Refuse = Callable[[str, str, str], None]


def check_plausibility_thresholds(rig: RigConfig, raw: JsonValue,
                                  limits: Mapping[str, _Limits],
                                  types: Mapping[str, MuscleType], ctx: Context) -> None:
    """Add an issue for each threshold of `safety.plausibility` that can never fire or
    always fires (`raw` is the parsed file, for lines; `types` each muscle's type, for
    its ratings)."""
    cfg = rig.safety.plausibility
    if not cfg.enabled:
        return
    node = _plausibility_node(raw)
    base = "safety.plausibility"

    def refuse(key: str, expected: str, found: str) -> None:
        ctx.add(line_of(node, key) or line_of(node), f"{base}.{key}", expected, found)

    _check_zero_force(cfg, [types[m.name] for m in rig.muscles if m.name in types], refuse)
    for m in rig.muscles:
        lim = limits.get(m.name)
        rating = types.get(m.name)
        if lim is not None and rating is not None:
            _check_muscle(cfg, m, lim, rating, refuse)


def _plausibility_node(raw: JsonValue) -> dict[str, JsonValue]:
    """The raw `safety.plausibility` mapping of the parsed file (empty if none)."""
    safety_node = raw.get("safety") if isinstance(raw, dict) else None
    node = (safety_node or {}).get("plausibility") if isinstance(safety_node, dict) else None
    return node if isinstance(node, dict) else {}


def _check_zero_force(cfg: PlausibilityConfig, rated: list[MuscleType],
                      refuse: _Refuse) -> None:
    """The zero-force check's share of the weight, and its smallest load against the
    muscles' rated loads."""
    if not cfg.force_zero_fraction > 0.0:
        refuse("force_zero_fraction", "above 0 (no reading is below 0 % of the weight: the "
               "zero-force check could never fire)", f"{cfg.force_zero_fraction:g}")
    elif cfg.force_zero_fraction > MAX_ZERO_FRACTION:
        refuse("force_zero_fraction", f"at most {MAX_ZERO_FRACTION:g} (a healthy load cell "
               "reads the weight give or take friction and the load's acceleration: a share "
               "this close to 1 faults it)", f"{cfg.force_zero_fraction:g}")
    if rated and cfg.force_check_min_load_kg > max(r.max_load_kg for r in rated):
        refuse("force_check_min_load_kg", f"at most {max(r.max_load_kg for r in rated):g} kg "
               "(the largest rated load: above it the zero-force check never runs)",
               f"{cfg.force_check_min_load_kg:g} kg")


def _check_muscle(cfg: PlausibilityConfig, m: MuscleConfig, lim: _Limits,
                  rating: MuscleType, refuse: _Refuse) -> None:
    """The thresholds against one muscle's limits and its type's rated force."""
    who = f"muscle {m.name!r}"
    if cfg.max_contraction <= lim.hard_max_contraction:
        refuse("max_contraction", f"above {who}'s hard contraction limit "
               f"{lim.hard_max_contraction:g} (a healthy muscle reaches it)",
               f"{cfg.max_contraction:g}")
    if cfg.min_contraction >= -lim.hard_max_pretension:
        refuse("min_contraction", f"below {who}'s hard pretension limit "
               f"{-lim.hard_max_pretension:g} (a healthy muscle stretches to it)",
               f"{cfg.min_contraction:g}")
    travel_mm = m.nominal_length_mm * (lim.hard_max_contraction + lim.hard_max_pretension)
    if cfg.length_jump_mm >= travel_mm:
        refuse("length_jump_mm", f"less than {who}'s whole travel ({travel_mm:.1f} mm): "
               "no jump could exceed it", f"{cfg.length_jump_mm:g} mm")
    if cfg.pressure_jump_bar >= lim.hard_max_pressure_bar:
        refuse("pressure_jump_bar", f"less than {who}'s hard pressure limit "
               f"({lim.hard_max_pressure_bar:g} bar): no jump could exceed it",
               f"{cfg.pressure_jump_bar:g} bar")
    if cfg.frozen_pressure_change_bar > lim.max_pressure_bar:
        refuse("frozen_pressure_change_bar", f"at most {who}'s pressure limit "
               f"({lim.max_pressure_bar:g} bar): the pressure never changes more, so a "
               "frozen length is never found", f"{cfg.frozen_pressure_change_bar:g} bar")
    if 2.0 * cfg.frozen_force_change_n >= rating.theoretical_force_n:
        refuse("frozen_force_change_n", f"less than half {who}'s rated force "
               f"({rating.theoretical_force_n:g} N): friction's swing is twice this, and "
               "no force map moves further, so a stuck load cell is never found",
               f"{cfg.frozen_force_change_n:g} N")
