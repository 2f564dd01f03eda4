"""A muscle's static force model F(pressure, contraction) and what is solved on it.

`ForceMap` interpolates a digitised or measured map (rows `pressure_bar, contraction,
force_n`) the way the reference equilibrium table was made: linearly in contraction
along each pressure curve, then linearly in pressure between neighbouring curves.
`SmoothForceFit` is the closed-form fit F = (a p + b) e^(c k) + (e p + f) k + g p + h
(k in %) of the DMSP-20's datasheet map. Both are pure Python: they run inside the
tick (safe pressure, plausibility, simulated plant). `equilibrium_contraction` and
`pressure_for_force` solve F = m g for the contraction or the pressure.
"""

from __future__ import annotations

import csv
import math
from bisect import bisect_right
from dataclasses import dataclass
from importlib import resources
from typing import Protocol

GRAVITY_M_S2 = 9.80665


class ForceModel(Protocol):
    def force_n(self, pressure_bar: float, contraction: float) -> float: ...


class ForceMap:
    """Piecewise-linear interpolation of a digitised force map.

    Outside a curve's contraction range the end segment is extended; above the top
    pressure curve the two top curves are extended linearly in pressure.
    """

    def __init__(self, points: list[tuple[float, float, float]]) -> None:
        self.points: tuple[tuple[float, float, float], ...] = tuple(points)
        levels: dict[float, list[tuple[float, float]]] = {}
        for p, x, f in points:
            levels.setdefault(p, []).append((x, f))
        self.pressures_bar = sorted(levels)
        if len(self.pressures_bar) < 2:
            raise ValueError("a force map needs at least two pressure curves")
        curves_x: list[list[float]] = []
        curves_f: list[list[float]] = []
        for p in self.pressures_bar:
            pts = sorted(levels[p])
            if len(pts) < 2:
                raise ValueError(f"the force map curve at {p} bar needs at least two points")
            curves_x.append([x for x, _ in pts])
            curves_f.append([f for _, f in pts])
        # Each curve with its segments' rises and widths (taken once, not per call) and
        # its last segment's start; the pressures' gaps and the last one's start.
        self._curves: list[_Curve] = [
            (xs, fs, [b - a for a, b in zip(fs, fs[1:], strict=False)],
             [b - a for a, b in zip(xs, xs[1:], strict=False)], len(xs) - 2)
            for xs, fs in zip(curves_x, curves_f, strict=True)]
        ps = self.pressures_bar
        self._p_gaps = [b - a for a, b in zip(ps, ps[1:], strict=False)]
        self._p_last = len(ps) - 2

    @classmethod
    def from_csv(cls, path: str | None = None) -> ForceMap:
        """Load `pressure_bar,contraction,force_n` rows (pamd's own column names; a lab's
        table in other units goes through `pamd.config.muscle_types`); default: the
        DMSP-20 map."""
        if path is None:
            return cls(package_map_points("dmsp20_force_map.csv"))
        with open(path) as fh:
            return cls(_points(fh.read()))

    def force_n(self, pressure_bar: float, contraction: float) -> float:
        ps = self.pressures_bar
        i = bisect_right(ps, pressure_bar) - 1
        if i < 0:
            i = 0
        elif i > self._p_last:
            i = self._p_last
        curves = self._curves
        f0 = _on_curve(curves[i], contraction)
        f1 = _on_curve(curves[i + 1], contraction)
        return f0 + (f1 - f0) * (pressure_bar - ps[i]) / self._p_gaps[i]


def package_map_points(name: str) -> list[tuple[float, float, float]]:
    """The rows of a map shipped in `pamd.data` (a datasheet's, digitised)."""
    return _points(resources.files("pamd.data").joinpath(name).read_text())


def _points(text: str) -> list[tuple[float, float, float]]:
    rows = [r for r in text.splitlines() if r and not r.startswith("#")]
    return [(float(r["pressure_bar"]), float(r["contraction"]), float(r["force_n"]))
            for r in csv.DictReader(rows)]


#: A pressure curve as `ForceMap` keeps it: contractions, forces, each segment's rise
#: and width, and the last segment's start.
_Curve = tuple[list[float], list[float], list[float], list[float], int]


def _on_curve(curve: _Curve, contraction: float) -> float:
    """Linear in contraction along one curve, its end segments extended (runs three
    times a tick: the plant twice, the plausibility once)."""
    xs, fs, rises, widths, last = curve
    j = bisect_right(xs, contraction) - 1
    if j < 0:
        j = 0
    elif j > last:
        j = last
    return fs[j] + rises[j] * (contraction - xs[j]) / widths[j]


@dataclass(frozen=True)
class SmoothForceFit:
    """F = (a p + b) e^(c k) + (e p + f) k + g p + h, p in bar, k contraction in %."""

    a: float = -10.1206
    b: float = 236.3164
    c: float = -0.3378
    e: float = -7.9242
    f: float = -1.8549
    g: float = 263.2552
    h: float = -238.7719

    def force_n(self, pressure_bar: float, contraction: float) -> float:
        k = contraction * 100.0
        p = pressure_bar
        return (self.a * p + self.b) * math.exp(self.c * k) + (self.e * p + self.f) * k + (
            self.g * p + self.h
        )


def equilibrium_contraction(
    model: ForceModel, pressure_bar: float, load_kg: float, lo: float = -0.06, hi: float = 0.30
) -> float:
    """Contraction where the muscle force equals the hanging load's weight.

    Force falls with contraction, so bisection on [lo, hi] finds it; the result is
    clamped to the bracket when the load is outside what the muscle can hold there.
    """
    weight_n = load_kg * GRAVITY_M_S2
    if model.force_n(pressure_bar, lo) < weight_n:
        return lo
    if model.force_n(pressure_bar, hi) > weight_n:
        return hi
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if model.force_n(pressure_bar, mid) > weight_n:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


def pressure_for_force(
    model: ForceModel, force_n: float, contraction: float, max_pressure_bar: float
) -> float:
    """Lowest pressure in [0, max] at which the muscle pulls `force_n` at `contraction`
    (force rises with pressure); 0 if it already does at 0 bar, max if it never does."""
    if model.force_n(0.0, contraction) >= force_n:
        return 0.0
    if model.force_n(max_pressure_bar, contraction) < force_n:
        return max_pressure_bar
    lo, hi = 0.0, max_pressure_bar
    for _ in range(50):
        mid = 0.5 * (lo + hi)
        if model.force_n(mid, contraction) >= force_n:
            hi = mid
        else:
            lo = mid
    return hi
