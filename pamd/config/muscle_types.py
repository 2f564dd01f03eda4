"""Each muscle's type, resolved with its config: the ratings its limits are held to,
and, once the limits are resolved, the type with its force map.

A datasheet type (`dmsp20`, `dmsp40`) is the registry's (`pamd.muscle_type`); its
figures are the manufacturer's, so the config may not restate them (a `custom`
section beside it is refused). A `custom` type's ratings are its config's `custom`
section and its map is the lab's table, read through the reader `pamd train` uses
(`pamd.client.training_tables`: CSV or MAT, units converted; a layer above the config, so it is
imported by name, only when a config names a custom map) and checked by
`pamd.muscle_type.mapcheck` against the muscle's resolved limits, naming the file
and row of what is wrong.
"""

from __future__ import annotations

import importlib
import os
from collections.abc import Mapping, Sequence
from dataclasses import replace
from typing import Protocol, cast

from pamd.config.schema import CustomMuscleConfig, MuscleConfig
from pamd.muscle_type import (
    TYPE_NAMES,
    MapBox,
    MapPoint,
    MuscleType,
    check_map,
    datasheet_type,
)
from pamd.muscle_type.custom import NAME as CUSTOM
from pamd.muscle_type.custom import custom_type
from pamd.wire.declare.jsonsafe import JsonObject, JsonValue
from pamd.wire.errors import ModelError
from pamd.wire.schema.engine import Context, line_of

#: the module whose `read_data` reads a lab's tables (`pamd train`'s reader)
TABLE_READER = "pamd.client.training_tables"
#: the map problems said in one config error (the first; a table has more rows)
PROBLEMS_SAID = 5


class _Table(Protocol):
    """One table as the reader gives it (`pamd.models.data.samples.Run`)."""

    source: str
    columns: Mapping[str, Sequence[float]]
    meta: JsonObject


class _Reader(Protocol):
    def read_data(self, paths: Sequence[str], muscle: str | None = None) -> list[_Table]: ...


class _Limits(Protocol):
    """A muscle's resolved limits (`pamd.config.loader.MuscleLimitsResolved`)."""

    @property
    def max_pressure_bar(self) -> float: ...

    @property
    def max_contraction(self) -> float: ...

    @property
    def max_pretension(self) -> float: ...


Ratings = MuscleType | CustomMuscleConfig


def ratings_of(m: MuscleConfig, item: JsonValue, base: str, ctx: Context) -> Ratings | None:
    """The ratings muscle `m` is held to (its datasheet type, or its `custom` section);
    None, with the reason in `ctx`, where its type cannot be resolved."""
    if m.type not in TYPE_NAMES:
        ctx.add(line_of(item, "type"), f"{base}.type", f"one of {', '.join(TYPE_NAMES)}",
                repr(m.type))
        return None
    if m.type == CUSTOM:
        if m.custom is None:
            ctx.add(line_of(item, "type"), f"{base}.custom", "a `custom` section with the "
                    "muscle's measured map (map_file) and its ratings (type custom assumes "
                    "nothing)", "none")
            return None
        if m.force_model != "map":
            ctx.add(line_of(item, "force_model"), f"{base}.force_model", "map (a custom "
                    "muscle's force model is its measured map)", repr(m.force_model))
        return m.custom
    t = datasheet_type(m.type)
    if m.custom is not None:
        ctx.add(line_of(item, "custom"), f"{base}.custom", f"no custom section (a {m.type}'s "
                "ratings and map are its datasheet's; type custom for a muscle of your own)",
                "a custom section")
    if m.force_model == "fit" and t.force_fit is None:
        ctx.add(line_of(item, "force_model"), f"{base}.force_model",
                f"map (no smooth fit of the {m.type}'s map has been derived)", "fit")
    span = t.nominal_length_range_mm
    if span is not None and not span[0] <= m.nominal_length_mm <= span[1]:
        ctx.add(line_of(item, "nominal_length_mm"), f"{base}.nominal_length_mm",
                f"{span[0]:g} to {span[1]:g} mm (the lengths a {m.type} is made in)",
                f"{m.nominal_length_mm:g} mm")
    return t


def resolve(m: MuscleConfig, ratings: Ratings, limits: _Limits, item: JsonValue, base: str,
            config_path: str, ctx: Context) -> MuscleType | None:
    """The muscle's type with its map: a datasheet type as it is; a custom one read from
    its table and checked against `limits` (None, the reason in `ctx`, if refused)."""
    if isinstance(ratings, MuscleType):
        return ratings
    node = item.get("custom") if isinstance(item, dict) else None
    where = line_of(node, "map_file") or line_of(item, "custom")
    path = os.path.join(os.path.dirname(os.path.abspath(config_path)),
                        os.path.expanduser(ratings.map_file))
    try:
        points, notes = read_map(path, m.nominal_length_mm)
    except ModelError as exc:
        ctx.add(where, f"{base}.custom.map_file", "a force map table pamd can read", str(exc))
        return None
    box = MapBox(limits.max_pressure_bar, -limits.max_pretension, limits.max_contraction,
                 (f"{base}.limits.max_pressure_bar", f"{base}.limits.max_pretension",
                  f"{base}.limits.max_contraction"))
    problems = check_map(points, path, box)
    if problems:
        more = len(problems) - PROBLEMS_SAID
        ctx.add(where, f"{base}.custom.map_file", "a force map fit to keep the load safe",
                "; ".join(problems[:PROBLEMS_SAID]) + (f" (and {more} more)" if more > 0
                                                        else ""))
        return None
    t = custom_type(points, path, max_pressure_bar=ratings.max_pressure_bar,
                    max_contraction=ratings.max_contraction,
                    max_pretension=ratings.max_pretension, max_load_kg=ratings.max_load_kg,
                    theoretical_force_n=ratings.theoretical_force_n,
                    inner_diameter_mm=ratings.inner_diameter_mm)
    return t if not notes else _noted(t, notes)


def read_map(path: str, nominal_length_mm: float | None = None
             ) -> tuple[list[MapPoint], list[str]]:
    """The rows of a force map table (CSV or MAT, through `pamd train`'s reader) and the
    unit conversions made; a length column is turned into contraction with the
    nominal length. `ModelError` names the file (and row or column) of what is wrong."""
    reader = cast(_Reader, importlib.import_module(TABLE_READER))
    tables = reader.read_data([path])
    if len(tables) != 1:
        raise ModelError(f"{path}: {len(tables)} tables in it; a force map is one table "
                         f"({', '.join(t.source for t in tables)})")
    table = tables[0]
    cols = table.columns
    where = table.source
    x = _contraction(cols, nominal_length_mm, where)
    missing = [n for n in ("pressure_bar", "force_n") if n not in cols]
    if missing:
        raise ModelError(f"{where}:1: no column {' or '.join(missing)} (columns: "
                         f"{', '.join(cols)}); a force map names pressure, force and "
                         "contraction (or length), each with its unit")
    offset = table.meta.get("row_offset", 1)
    first = offset if isinstance(offset, int) else 1
    p = [float(v) for v in cols["pressure_bar"]]
    f = [float(v) for v in cols["force_n"]]
    points = [MapPoint(p[i], x[i], f[i], first + i) for i in range(len(p))]
    conversions = table.meta.get("conversions") or []
    notes = [str(n) for n in conversions] if isinstance(conversions, list) else []
    return points, notes


def _contraction(cols: Mapping[str, Sequence[float]], nominal_length_mm: float | None,
                 where: str) -> list[float]:
    if "contraction" in cols:
        return [float(v) for v in cols["contraction"]]
    if "length_mm" in cols and nominal_length_mm:
        return [(nominal_length_mm - float(v)) / nominal_length_mm for v in cols["length_mm"]]
    raise ModelError(f"{where}:1: no contraction column (contraction, `contraction [%]`, or "
                     "a length with the muscle's nominal_length_mm)")


def _noted(t: MuscleType, notes: list[str]) -> MuscleType:
    """The type whose source says how its table's units were read."""
    return replace(t, source=f"{t.source} ({'; '.join(notes)})")
