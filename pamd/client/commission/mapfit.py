"""From the holds of `pamd commission --measure-map` to a muscle's static map (numpy,
after the run; never in the tick).

Per hold (a level under a load, reached on one branch of the friction loop): the means
of the pressure, the force and the contraction over its last `TAIL_S`, and whether the
load hung still then (`SETTLED_CONTRACTION`) at its level (`LEVEL_TOL_BAR`); a hold that
did not is left out of the map and said.

The static map. Friction holds a muscle back both ways by about the same force, so on
the rising branch it rests short of where its static force equals the load
(F(p, x_rising) = W + Ff) and on the falling branch past it (F(p, x_falling) = W - Ff):
the static map's point is midway, x = (x_rising + x_falling) / 2, with the force the
load cell read there (the load's weight, as a still load pulls). Both branches are
kept (`MeasuredMap.holds`, written beside the map); only a level measured on both gives
a point of the map. A level needs two loads to be a curve (`Curve`).

Completed for use (`complete`): a muscle's map must reach its limits (0 bar to the
pressure limit, the pretension limit to the contraction limit; `pamd.muscle_type.
mapcheck`), which hanging loads cannot all reach (no load pulls a vented muscle
shorter than its nominal length). Each measured curve is extended linearly past its
last points, and a curve at 0 bar or at the pressure limit, where none was measured,
is extrapolated linearly in pressure from the nearest two (a braided muscle's force is
about affine in pressure); an extrapolated 0 bar curve pulls nothing from the nominal
length on (that length is the unpressurised, unloaded one: a vented muscle is slack
there, and a load hung on it stretches it). Where that would let the force rise with
contraction or fall with pressure, the extended value is lowered to just below its
neighbour: a muscle taken as weaker where nobody measured it (a higher safe pressure,
never a lower one). Every row says whether it is measured (`measured`: 1 on a curve's measured
span, 0 extended). What the report compares (`compare`) is the measured range only.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from pamd.client.commission.mapsweep import FALLING, RISING
from pamd.client.commission.probe import Probe
from pamd.muscle_type import ForceMap, ForceModel

#: the tail of a hold that is measured, s
TAIL_S = 0.5
#: a load whose contraction changes less than this over the tail hangs still enough: a
#: pressure loop's dither lets a muscle creep slowly inside its friction band (0.1 mm/s
#: on the simulated DMSP-40 seconds after a level is reached), which moves the midline
#: between two branches 0.3-0.8 % apart by less than 0.03 %
SETTLED_CONTRACTION = 0.0005
#: a hold's mean pressure within this of its level
LEVEL_TOL_BAR = 0.05
#: how far an extended force is kept from its neighbour (rising with pressure, falling
#: with contraction), N
MONOTONE_STEP_N = 1.0
#: the points per curve `compare` judges the measured range on
COMPARE_POINTS = 41


@dataclass(frozen=True)
class Hold:
    """One hold of the sweep: a level under a load, reached on one branch."""

    load_kg: float
    level_bar: float
    branch: int  # RISING (+1) or FALLING (-1)
    pressure_bar: float
    force_n: float
    contraction: float
    moved_mm: float  # over the tail
    problem: str = ""  # why it is left out ("" if kept)


@dataclass(frozen=True)
class Point:
    """A point of the static map: a level and a load, midway between the branches."""

    level_bar: float
    load_kg: float
    contraction: float
    force_n: float
    half_width: float  # half the loop's width in contraction: (falling - rising) / 2


@dataclass
class MeasuredMap:
    holds: list[Hold] = field(default_factory=list)
    points: list[Point] = field(default_factory=list)
    #: level -> its points by contraction (the levels with at least two)
    curves: dict[float, list[Point]] = field(default_factory=dict)
    #: levels measured on one load only, or on one branch only (said, not mapped)
    unused: list[str] = field(default_factory=list)

    def force_map(self) -> ForceMap:
        """The measured curves as a map (no completion)."""
        return ForceMap([(p, q.contraction, q.force_n) for p, qs in self.curves.items()
                         for q in qs])


def holds_of(probe: Probe, muscle: str, phase: int, load_kg: float,
             steps: Sequence[tuple[float, int]], nominal_length_mm: float) -> list[Hold]:
    """The holds of one load's plan (`steps`: each step's level and branch, 0 for those
    that measure nothing), from the probe's rows of `phase`."""
    t, ph, seg = probe.column("t"), probe.column("phase"), probe.column("segment")
    cols = {c: probe.column(f"{muscle}.{c}") for c in ("pressure", "force", "length")}
    out = []
    for k, (level, branch) in enumerate(steps):
        if branch == 0:
            continue
        idx = np.flatnonzero((ph == phase) & (seg == k + 1))
        if len(idx) < 3:
            out.append(Hold(load_kg, level, branch, math.nan, math.nan, math.nan, math.nan,
                            "not reached (the plan stopped before it)"))
            continue
        tail = idx[t[idx] >= t[idx[-1]] - TAIL_S]
        p, f = float(np.mean(cols["pressure"][tail])), float(np.mean(cols["force"][tail]))
        length = cols["length"][tail]
        slope = float(np.polyfit(t[tail] - t[tail[0]], length, 1)[0]) if len(tail) > 2 else 0.0
        moved = abs(slope) * TAIL_S
        x = (nominal_length_mm - float(np.mean(length))) / nominal_length_mm
        problem = ""
        if moved > SETTLED_CONTRACTION * nominal_length_mm:
            problem = (f"still moving ({moved:.2f} mm over the last {TAIL_S:g} s): hold the "
                       "levels longer (--map-hold-s)")
        elif abs(p - level) > LEVEL_TOL_BAR:
            problem = (f"the pressure stood at {p:.3f} bar, not its level: a guard held it "
                       "back, or the supply")
        out.append(Hold(load_kg, level, branch, p, f, x, moved, problem))
    return out


def build(holds: Sequence[Hold]) -> MeasuredMap:
    """The static map's points and curves from the holds (see the module's doc)."""
    out = MeasuredMap(holds=list(holds))
    pairs: dict[tuple[float, float], dict[int, Hold]] = {}
    for h in holds:
        if not h.problem:
            pairs.setdefault((h.level_bar, h.load_kg), {})[h.branch] = h
    for (level, load), branches in sorted(pairs.items()):
        up, down = branches.get(RISING), branches.get(FALLING)
        if up is None or down is None:
            continue
        out.points.append(Point(level, load, 0.5 * (up.contraction + down.contraction),
                                0.5 * (up.force_n + down.force_n),
                                0.5 * (down.contraction - up.contraction)))
    by_level: dict[float, list[Point]] = {}
    for q in out.points:
        by_level.setdefault(q.level_bar, []).append(q)
    for level in sorted({h.level_bar for h in holds}):
        qs = sorted(by_level.get(level, []), key=lambda q: q.contraction)
        if len(qs) >= 2:
            out.curves[level] = qs
        else:
            out.unused.append(f"{level:g} bar: {len(qs)} load(s) measured on both branches "
                              "(a curve needs two)")
    return out


@dataclass(frozen=True)
class Row:
    pressure_bar: float
    contraction: float
    force_n: float
    measured: bool


def complete(curves: dict[float, list[Point]], max_pressure_bar: float,
             min_contraction: float, max_contraction: float) -> list[Row]:
    """The measured curves completed to the limits (see the module's doc), as rows on a
    common contraction grid: every measured contraction and the limits."""
    levels = sorted(curves)
    grid = sorted({min_contraction, max_contraction, *([0.0] if min_contraction < 0.0 <
                                                       max_contraction else []),
                   *(q.contraction for qs in curves.values() for q in qs
                     if min_contraction < q.contraction < max_contraction)})
    table: dict[float, list[float]] = {}
    known: dict[float, list[bool]] = {}
    for p in levels:
        xs = [q.contraction for q in curves[p]]
        fs = [q.force_n for q in curves[p]]
        table[p] = [_along(xs, fs, x) for x in grid]
        known[p] = [xs[0] <= x <= xs[-1] for x in grid]
    for edge, (a, b) in ((0.0, levels[:2]), (max_pressure_bar, levels[-2:])):
        if edge not in table:
            table[edge] = [fa + (fb - fa) * (edge - a) / (b - a)
                           for fa, fb in zip(table[a], table[b], strict=True)]
            known[edge] = [False] * len(grid)
    if not any(known[0.0]):  # vented at its nominal length a muscle pulls nothing
        table[0.0] = [min(f, 0.0) if x >= 0.0 else f for f, x in zip(table[0.0], grid,
                                                                      strict=True)]
    _monotone(table, known)
    return [Row(p, x, round(table[p][i], 2), known[p][i]) for p in sorted(table)
            for i, x in enumerate(grid)]


def _along(xs: list[float], fs: list[float], x: float) -> float:
    """Linear along a curve, its end segments extended (`ForceMap`'s rule)."""
    j = min(max(int(np.searchsorted(xs, x, side="right")) - 1, 0), len(xs) - 2)
    return fs[j] + (fs[j + 1] - fs[j]) * (x - xs[j]) / (xs[j + 1] - xs[j])


def _monotone(table: dict[float, list[float]], known: dict[float, list[bool]]) -> None:
    """Lower the extended values (never a measured one) until the force falls with
    contraction along each curve and rises with pressure between curves."""
    levels = sorted(table)
    for _ in range(len(levels) + len(next(iter(table.values())))):
        changed = False
        for p in levels:  # along each curve (a value left of a measured one is not
            f, ok = table[p], known[p]  # lowered: that leaves it to check_map)
            for i in range(1, len(f)):
                if not ok[i] and f[i] > f[i - 1] - MONOTONE_STEP_N:
                    f[i], changed = f[i - 1] - MONOTONE_STEP_N, True
        for lo, hi in zip(reversed(levels[:-1]), reversed(levels[1:]), strict=True):
            f, g, ok = table[lo], table[hi], known[lo]
            for i in range(len(f)):
                if not ok[i] and f[i] > g[i] - MONOTONE_STEP_N:
                    f[i], changed = g[i] - MONOTONE_STEP_N, True
        if not changed:
            return


@dataclass(frozen=True)
class Comparison:
    """The measured map against another (the type's, the truth), over the measured
    range: at its points, and along each curve's measured span (relative to the other
    map's force)."""

    points: int
    points_max: float
    points_rms: float
    span_max: float
    span_rms: float
    worst: str

    def as_dict(self) -> dict[str, object]:
        return dict(self.__dict__)


def compare(measured: MeasuredMap, other: ForceModel) -> Comparison:
    """Relative force errors |F_measured - F_other| / F_other (see `Comparison`)."""
    fm = measured.force_map()
    at_points = [(q.level_bar, q.contraction, q.force_n) for qs in measured.curves.values()
                 for q in qs]
    e_points = [abs(f - other.force_n(p, x)) / abs(other.force_n(p, x))
                for p, x, f in at_points]
    e_span: list[float] = []
    worst = (0.0, "")
    for p, qs in measured.curves.items():
        for x in np.linspace(qs[0].contraction, qs[-1].contraction, COMPARE_POINTS):
            ref = other.force_n(p, float(x))
            e = abs(fm.force_n(p, float(x)) - ref) / abs(ref)
            e_span.append(e)
            if e > worst[0]:
                worst = (e, f"{p:g} bar, {100 * x:.1f} %: {fm.force_n(p, float(x)):.0f} N "
                            f"measured, {ref:.0f} N")
    return Comparison(len(e_points), max(e_points), _rms(e_points), max(e_span),
                      _rms(e_span), worst[1])


def _rms(values: list[float]) -> float:
    return math.sqrt(sum(v * v for v in values) / len(values))


def map_csv(rows: Sequence[Row], muscle: str, source: str) -> str:
    """The map's table as `muscles[].custom.map_file` reads it, with what it is."""
    head = (f"# {muscle}'s static force map, measured by pamd commission --measure-map "
            f"({source}).\n# Each curve: the settled contraction under each load, midway "
            "between the rising and falling\n# branches, at the load cell's force. "
            "measured: 1 on a curve's measured span, 0 where\n# the map is extended to "
            "the limits (linearly; lowered where needed to stay monotone).\n"
            "pressure_bar,contraction,force_n,measured\n")
    return head + "".join(f"{r.pressure_bar:g},{r.contraction:.6g},{r.force_n:.2f},"
                          f"{int(r.measured)}\n" for r in rows)


def branches_csv(holds: Sequence[Hold], muscle: str) -> str:
    """Every hold, both branches: what the map was made of."""
    head = (f"# {muscle}: every hold of pamd commission --measure-map. branch: +1 reached "
            "with the pressure rising,\n# -1 falling. used: 0 where the hold was left out "
            "(see the report).\n"
            "load_kg,level_bar,branch,pressure_bar,contraction,force_n,moved_mm,used\n")
    return head + "".join(
        f"{h.load_kg:g},{h.level_bar:g},{h.branch},{h.pressure_bar:.4f},{h.contraction:.6f},"
        f"{h.force_n:.2f},{h.moved_mm:.4f},{int(not h.problem)}\n" for h in holds)
