"""Is a force map fit to keep a load safe? The checks a map passes before any muscle
uses it, each naming the table and its rows.

A map is rows (pressure, contraction, force), grouped into pressure curves by equal
pressure; `ForceMap` interpolates linearly along each curve and between neighbouring
curves, and extends the end segments and the end curves beyond the data. What the
physics of a braided muscle demands of it, and so what is refused:

* a number that is not finite (NaN, inf): nothing can be interpolated through it;
* too few points: fewer than two pressure curves, or a curve of one point (a curve's
  slope, and the force's rise between curves, need two of each);
* the force not falling with contraction along a curve: at a fixed pressure a muscle
  pulls less the shorter it is (the braid's angle grows towards its limit) - a rise
  means a mislabelled column, a sign error or a stuck sensor;
* the force not rising with pressure at a fixed contraction: at a fixed length more
  pressure pulls harder (the force is about affine in pressure). Checked exactly where
  the map is used: between every two neighbouring curves over the whole contraction
  range the limits allow, the curves' extensions included (the difference of two
  piecewise-linear curves is piecewise linear, so its breakpoints and the range's ends
  are where it is smallest);
* a map that does not reach the configured limits: its curves must span the pressure
  range (0 to the pressure limit) and its points the contraction range (the pretension
  limit to the contraction limit), or the rig would run on an extrapolation nobody
  measured.
"""

from __future__ import annotations

import math
from bisect import bisect_right
from collections.abc import Sequence
from dataclasses import dataclass

#: within this the map reaches a limit (a rounding of the table's numbers)
REACH_TOL = 1e-6


@dataclass(frozen=True)
class MapPoint:
    """One row of a map: where it sits in its table (`row`: the file's line, or a MAT
    variable's element)."""

    pressure_bar: float
    contraction: float
    force_n: float
    row: int


@dataclass(frozen=True)
class MapBox:
    """The region a map must cover and be monotone over: pressure 0 to the limit,
    contraction from the pretension limit (as a negative contraction) to the contraction
    limit. `limit_names` say which config keys set them, for the message."""

    max_pressure_bar: float
    min_contraction: float
    max_contraction: float
    limit_names: tuple[str, str, str] = ("max_pressure_bar", "max_pretension",
                                         "max_contraction")


class _Curve:
    """One pressure curve: its points by contraction, as `ForceMap` interpolates it."""

    def __init__(self, pressure_bar: float, points: list[MapPoint]) -> None:
        self.pressure_bar = pressure_bar
        self.points = sorted(points, key=lambda q: q.contraction)
        self.xs = [q.contraction for q in self.points]

    def force_n(self, x: float) -> float:
        """Linear along the curve, its end segments extended (`ForceMap`'s rule)."""
        xs, pts = self.xs, self.points
        j = min(max(bisect_right(xs, x) - 1, 0), len(xs) - 2)
        a, b = pts[j], pts[j + 1]
        return a.force_n + (b.force_n - a.force_n) * (x - a.contraction) / (
            b.contraction - a.contraction)

    def nearest(self, x: float) -> MapPoint:
        return min(self.points, key=lambda q: abs(q.contraction - x))


def check_map(points: Sequence[MapPoint], source: str, box: MapBox | None = None) -> list[str]:
    """The problems of a map (empty: none), each starting `source:row:`. `box`: the
    limits it must reach and be monotone within (None: over its own data)."""
    bad = [f"{source}:{q.row}: {name} is not a finite number ({value!r}); every cell of "
           "a force map must be one"
           for q in points for name, value in (("pressure_bar", q.pressure_bar),
                                                 ("contraction", q.contraction),
                                                 ("force_n", q.force_n))
           if not math.isfinite(value)]
    if bad:
        return bad
    curves = _curves(points)
    problems = _too_few(curves, points, source)
    if problems:
        return problems
    for c in curves:
        problems += _falls_along(c, source)
    if problems:
        return problems
    if box is not None:
        problems += _reaches(curves, points, source, box)
    lo = box.min_contraction if box is not None else min(q.contraction for q in points)
    hi = box.max_contraction if box is not None else max(q.contraction for q in points)
    for below, above in zip(curves, curves[1:], strict=False):
        problems += _rises_between(below, above, lo, hi, source)
    return problems


def _curves(points: Sequence[MapPoint]) -> list[_Curve]:
    levels: dict[float, list[MapPoint]] = {}
    for q in points:
        levels.setdefault(q.pressure_bar, []).append(q)
    return [_Curve(p, levels[p]) for p in sorted(levels)]


def _too_few(curves: list[_Curve], points: Sequence[MapPoint], source: str) -> list[str]:
    if len(curves) < 2:
        return [f"{source}: {len(points)} point(s) on {len(curves)} pressure curve(s): a map "
                "needs at least two curves of at least two points each (rows are grouped "
                "into curves by equal pressure_bar)"]
    out = []
    for c in curves:
        if len(c.points) < 2:
            out.append(f"{source}:{c.points[0].row}: the {c.pressure_bar:g} bar curve has one "
                       "point; a curve needs at least two (rows are grouped into curves by "
                       "equal pressure_bar: round a measured pressure to its set level)")
        for a, b in zip(c.points, c.points[1:], strict=False):
            if b.contraction == a.contraction:
                out.append(f"{source}:{a.row},{b.row}: two forces at contraction "
                           f"{a.contraction:g} on the {c.pressure_bar:g} bar curve")
    return out


def _falls_along(c: _Curve, source: str) -> list[str]:
    out = []
    for a, b in zip(c.points, c.points[1:], strict=False):
        if not b.force_n < a.force_n:
            out.append(
                f"{source}:{b.row}: the force does not fall with contraction on the "
                f"{c.pressure_bar:g} bar curve ({a.force_n:g} N at {a.contraction:g} in row "
                f"{a.row}, {b.force_n:g} N at {b.contraction:g} here): at a fixed pressure a "
                "muscle pulls less the shorter it is; check the columns' order and signs")
    return out


def _rises_between(below: _Curve, above: _Curve, lo: float, hi: float,
                   source: str) -> list[str]:
    """F(above) > F(below) at every contraction in [lo, hi] (exact: see the module)."""
    xs = sorted({lo, hi, *(x for x in below.xs + above.xs if lo < x < hi)})
    for x in xs:
        f0, f1 = below.force_n(x), above.force_n(x)
        if not f1 > f0:
            a, b = below.nearest(x), above.nearest(x)
            how = ("" if min(below.xs) <= x <= max(below.xs) and min(above.xs) <= x <= max(
                above.xs) else " (where a curve is extended past its last point)")
            return [f"{source}:{a.row},{b.row}: the force does not rise with pressure at "
                    f"contraction {x:g}{how}: {f0:.1f} N at {below.pressure_bar:g} bar (near "
                    f"row {a.row}) but {f1:.1f} N at {above.pressure_bar:g} bar (near row "
                    f"{b.row}); at a fixed length more pressure pulls harder"]
    return []


def _reaches(curves: list[_Curve], points: Sequence[MapPoint], source: str,
             box: MapBox) -> list[str]:
    """The curves span 0 bar to the pressure limit, the points the contraction limits."""
    out = []
    p_key, pre_key, con_key = box.limit_names
    low, high = curves[0], curves[-1]
    if low.pressure_bar > REACH_TOL or high.pressure_bar < box.max_pressure_bar - REACH_TOL:
        out.append(f"{source}:{low.points[0].row},{high.points[0].row}: pressure curves from "
                   f"{low.pressure_bar:g} to {high.pressure_bar:g} bar; the limits need 0 to "
                   f"{box.max_pressure_bar:g} bar ({p_key}): extend the map to them, or set "
                   f"{p_key} inside it")
    first = min(points, key=lambda q: q.contraction)
    last = max(points, key=lambda q: q.contraction)
    if first.contraction > box.min_contraction + REACH_TOL or \
            last.contraction < box.max_contraction - REACH_TOL:
        out.append(f"{source}:{first.row},{last.row}: contraction from {first.contraction:g} "
                   f"(row {first.row}) to {last.contraction:g} (row {last.row}); the limits "
                   f"need {box.min_contraction:g} ({pre_key}) to {box.max_contraction:g} "
                   f"({con_key}): extend the map to them, or set the limits inside it")
    return out
