"""A model's training domain: where its training data lay, written into the model file
(`provenance.domain`), and the tick's test of whether what the model is fed lies there.

Why a domain of its own, not the inputs' ranges: each input can lie inside its range
while the combination was never seen (a length the muscle never had under that load),
and the ranges say nothing of the pressure. Why not a grid of occupied cells (the
coverage grid `pamd train` wrote before): a hanging-load sweep holds its force
constant to about +-5 N per load, so its data sit in narrow force *bands* with empty
cells between them, and a load between two trained loads would be "off the data",
though interpolating between bands is the model's job. Extrapolating beyond the
outermost band is not.

The rule (`RULE`):

* The **force axis is banded**: the training forces, sorted, split where two
  neighbours lie more than `GAP_FRACTION` of the force scale apart (the gap between
  two hanging loads); a band wider than `BAND_FRACTION` of the scale (a force that
  varies continuously, e.g. a spring or an antagonist) is cut into equal sub-bands no
  wider. The force scale is the larger of the data's force span and its largest
  force: one hanging load (+-5 N) is one band, not ten slivers of its noise. Each band
  keeps the least and the greatest value of every other input and of the output (the
  pressure) among its samples.
* A point is **inside** when its force lies within the outermost bands (widened by
  `MARGIN_FRACTION` of the force scale: a load's inertia in a faster motion than the
  sweep's) and every other input and the output lie within the bounds at that force:
  a band's own bounds inside a band, between two adjacent bands the bounds
  interpolated linearly in force (a load between two trained loads reaches lengths
  and pressures between theirs). Each bound is widened by `MARGIN_FRACTION` of its
  column's whole training span (sensor noise, a band's sparse edges).
* A model without a force input has one band: its inputs' and output's ranges.

On the tick (`DomainTable`): the bounds are tabulated over `TABLE_CELLS` equal cells of
the (widened) force axis, each cell holding the loosest bounds over it (the bounds are
piecewise linear in force, so their extremes over a cell lie at its ends or at a band
edge inside it); a test is one index computation and a few comparisons, no allocation.

Older model files (no domain) are read as far as they allow (`domain_of`): from the
coverage grid (`provenance.coverage`: the occupied cells of 10 bins per input, banded
the same way, coarser: a cell's width) or, without one, from the inputs' ranges
alone (a box: combinations inside it cannot be judged); `Domain.derived` says which.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from pamd.models.contract import InverseModel
from pamd.wire.declare.jsonsafe import JsonObject, JsonValue
from pamd.wire.errors import ModelError

#: A gap between neighbouring training forces wider than this share of the force scale
#: (the larger of their span and the largest force) separates two bands (two hanging
#: loads; +-5 N of noise and inertia within a load).
GAP_FRACTION = 0.02
#: A band wider than this share of the force scale is cut into equal sub-bands.
BAND_FRACTION = 0.10
#: Each bound is widened by this share of its column's whole training span (the force
#: axis: of the force scale).
MARGIN_FRACTION = 0.02
#: Cells of the tick's table over the force axis.
TABLE_CELLS = 256
#: The axis a domain is banded along, when the model has it as an input.
AXIS = "force_n"
VERSION = 1
RULE = ("inside when the force lies within the trained force bands (a load between two "
        "trained loads included, beyond the outermost not) and every other input and the "
        "pressure lie within the bounds seen at that force (interpolated between adjacent "
        f"bands), each bound widened by {100 * MARGIN_FRACTION:g} % of its span")


@dataclass(frozen=True)
class Band:
    """One band of the force axis: its force range and, per bounded column, the least
    and greatest value its samples had."""

    axis_lo: float
    axis_hi: float
    lo: tuple[float, ...]
    hi: tuple[float, ...]


@dataclass(frozen=True)
class Domain:
    """Where a model's training data lay (see the module doc). `columns` are the bounded
    columns (the model's inputs but the axis, then its output), `margins` their
    widening, `axis_margin` the force axis's; `derived` says from what it was made."""

    axis: str | None
    columns: tuple[str, ...]
    bands: tuple[Band, ...]
    margins: tuple[float, ...]
    axis_margin: float
    derived: str = "training data"

    @property
    def axis_range(self) -> tuple[float, float]:
        """The force range inside the domain (margin included); (-inf, inf) unbanded."""
        if self.axis is None:
            return -math.inf, math.inf
        return self.bands[0].axis_lo - self.axis_margin, self.bands[-1].axis_hi + self.axis_margin

    def overall(self, column: str) -> tuple[float, float]:
        """The column's bounds over every band (margin included)."""
        j = self.columns.index(column)
        m = self.margins[j]
        return (min(b.lo[j] for b in self.bands) - m, max(b.hi[j] for b in self.bands) + m)

    def bounds_at(self, force_n: float) -> tuple[list[float], list[float]] | None:
        """(lo, hi) of every column at this force (margins included), or None when the
        force lies outside the bands."""
        bands = self.bands
        if self.axis is not None:
            a_lo, a_hi = self.axis_range
            if not a_lo <= force_n <= a_hi:
                return None
        k = _bracket(bands, force_n) if self.axis is not None else (0, 0, 0.0)
        i, j, t = k
        lo = [(1 - t) * a + t * b - m for a, b, m in
              zip(bands[i].lo, bands[j].lo, self.margins, strict=True)]
        hi = [(1 - t) * a + t * b + m for a, b, m in
              zip(bands[i].hi, bands[j].hi, self.margins, strict=True)]
        return lo, hi

    def to_json(self) -> JsonObject:
        return {
            "version": VERSION, "rule": RULE, "derived": self.derived, "axis": self.axis,
            "columns": list(self.columns), "margins": list(self.margins),
            "axis_margin": self.axis_margin,
            "bands": [{"axis": [b.axis_lo, b.axis_hi] if self.axis is not None else None,
                       "lo": list(b.lo), "hi": list(b.hi)} for b in self.bands]}

    def describe(self) -> str:
        """One line for the operator: the bands (as forces and loads) and the bounds."""
        parts = []
        if self.axis is not None:
            loads = ", ".join(f"{0.5 * (b.axis_lo + b.axis_hi):.0f}" for b in self.bands)
            parts.append(f"{len(self.bands)} force band(s) at {loads} N")
        for c in self.columns:
            lo, hi = self.overall(c)
            parts.append(f"{c} {lo:.4g}..{hi:.4g}")
        return "; ".join(parts) + f" (from its {self.derived})"


def _bracket(bands: Sequence[Band], f: float) -> tuple[int, int, float]:
    """(i, j, t): the bounds at force f are (1 - t) band i's + t band j's."""
    if f <= bands[0].axis_hi:
        return 0, 0, 0.0
    for i in range(len(bands) - 1):
        a, b = bands[i], bands[i + 1]
        if f <= b.axis_lo:
            if f <= a.axis_hi:
                return i, i, 0.0
            return i, i + 1, (f - a.axis_hi) / (b.axis_lo - a.axis_hi)
        if f <= b.axis_hi:
            return i + 1, i + 1, 0.0
    n = len(bands) - 1
    return n, n, 0.0


# -- derivation -------------------------------------------------------------------------
def derive(X: np.ndarray, y: np.ndarray, inputs: Sequence[str], output: str) -> Domain:
    """The domain of training inputs X (n x d, in `inputs` order) and outputs y."""
    Xa = np.asarray(X, dtype=np.float64)
    cols = [Xa[:, i] for i, n in enumerate(inputs) if n != AXIS]
    names = tuple(n for n in inputs if n != AXIS) + (output,)
    C = np.column_stack([*cols, np.asarray(y, dtype=np.float64)])
    span = C.max(axis=0) - C.min(axis=0)
    margins = tuple(float(v) for v in MARGIN_FRACTION * span)
    if AXIS not in inputs:
        band = Band(-math.inf, math.inf, tuple(C.min(axis=0).tolist()),
                    tuple(C.max(axis=0).tolist()))
        return Domain(None, names, (band,), margins, 0.0)
    f = Xa[:, list(inputs).index(AXIS)]
    order = np.argsort(f, kind="stable")
    fs, Cs = f[order], C[order]
    scale = max(float(fs[-1] - fs[0]), float(np.abs(fs).max()))
    bands = []
    for a, b in _band_edges(fs, scale):
        part = Cs[a:b]
        bands.append(Band(float(fs[a]), float(fs[b - 1]), tuple(part.min(axis=0).tolist()),
                          tuple(part.max(axis=0).tolist())))
    return Domain(AXIS, names, tuple(bands), margins, MARGIN_FRACTION * scale)


def _band_edges(fs: np.ndarray, scale: float) -> list[tuple[int, int]]:
    """[start, end) index ranges of the bands of sorted forces `fs` (force scale
    `scale`)."""
    n = fs.size
    if scale <= 0.0:
        return [(0, n)]
    cuts = np.flatnonzero(np.diff(fs) > GAP_FRACTION * scale) + 1
    edges = [0, *cuts.tolist(), n]
    out = []
    for a, b in zip(edges[:-1], edges[1:], strict=True):
        width = float(fs[b - 1] - fs[a])
        pieces = max(1, math.ceil(width / (BAND_FRACTION * scale) - 1e-9))
        if pieces == 1:
            out.append((a, b))
            continue
        bounds = fs[a] + width * np.arange(1, pieces) / pieces
        inner = [a, *(a + np.searchsorted(fs[a:b], bounds, side="right")).tolist(), b]
        out += [(s, e) for s, e in zip(inner[:-1], inner[1:], strict=True) if e > s]
    return out


def from_coverage(cov: JsonObject, inputs: Sequence[str], output_lo: float,
                  output_hi: float) -> Domain | None:
    """An older file's coverage grid (`provenance.coverage`: occupied cells of `bins`
    equal bins per input) as a domain: each occupied force bin a band, its other
    inputs' bounds the occupied bins' edges, the output the model's output range.
    None if the grid does not fit the inputs."""
    try:
        if list(cov["inputs"]) != list(inputs):
            return None
        bins = int(cov["bins"])
        lo = np.array(cov["lo"], dtype=np.float64)
        hi = np.array(cov["hi"], dtype=np.float64)
        cells = np.array(cov["cells"], dtype=np.int64)
    except (KeyError, TypeError, ValueError):
        return None
    d = len(inputs)
    if bins < 1 or lo.shape != (d,) or hi.shape != (d,) or cells.size == 0:
        return None
    idx = np.stack([(cells // bins ** (d - 1 - j)) % bins for j in range(d)], axis=1)
    width = (hi - lo) / bins
    # each occupied cell as its two extreme corners, banded as training samples are
    corners = np.concatenate([lo + idx * width, lo + (idx + 1) * width])
    pts = np.concatenate([corners, corners])  # each with the output's least and greatest
    y = np.repeat([output_lo, output_hi], corners.shape[0])
    dom = derive(pts, y, inputs, "pressure_bar")
    return _with(dom, "coverage grid (an older file: coarser, a tenth of each range)")


def from_ranges(model: InverseModel) -> Domain:
    """The box of the inputs' and output's ranges (a file with nothing finer)."""
    names = [v.name for v in model.inputs]
    X = np.array([[v.min for v in model.inputs], [v.max for v in model.inputs]])
    y = np.array([model.output.min, model.output.max])
    dom = derive(X, y, names, model.output.name)
    if dom.axis is not None:  # one band over the whole force range, not its two ends
        b0, b1 = dom.bands[0], dom.bands[-1]
        dom = Domain(dom.axis, dom.columns, (Band(b0.axis_lo, b1.axis_hi,
                                                   tuple(map(min, b0.lo, b1.lo)),
                                                   tuple(map(max, b0.hi, b1.hi))),),
                     dom.margins, dom.axis_margin)
    return _with(dom, "input ranges (an older file: combinations within them cannot be "
                      "judged)")


def _with(dom: Domain, derived: str) -> Domain:
    return Domain(dom.axis, dom.columns, dom.bands, dom.margins, dom.axis_margin, derived)


# -- the file -----------------------------------------------------------------------------
def from_json(doc: object, inputs: Sequence[str], output: str) -> Domain:
    """A domain as the model file states it; ModelError names the field."""
    where = "provenance.domain"
    if not isinstance(doc, dict):
        raise ModelError(f"field {where}: expected an object")
    axis, columns, margins, axis_margin, raw, derived = _domain_fields(doc, where)
    want_axis = AXIS if AXIS in inputs else None
    want_cols = tuple(n for n in inputs if n != AXIS) + (output,)
    if axis != want_axis or columns != want_cols:
        raise ModelError(f"field {where}: bounds {list(columns)} along {axis!r} do not fit "
                         f"the model's inputs and output {[*inputs, output]}")
    k = len(columns)
    if len(margins) != k or not isinstance(raw, list) or not raw:
        raise ModelError(f"field {where}: {k} margins and at least one band expected")
    bands: list[Band] = []
    for i, b in enumerate(raw):
        bands.append(_band_from_json(b, f"{where}.bands[{i}]", axis, k,
                                     bands[-1] if bands else None))
    _check_margins_and_bands(margins, axis_margin, axis, len(bands), where)
    return Domain(axis, columns, tuple(bands), margins, axis_margin, derived)


def _check_margins_and_bands(margins: tuple[float, ...], axis_margin: float,
                             axis: JsonValue, n_bands: int, where: str) -> None:
    """Margins finite and >= 0; one band where there is no force axis."""
    if not all(math.isfinite(v) and v >= 0 for v in (*margins, axis_margin)):
        raise ModelError(f"field {where}: margins must be finite and >= 0")
    if axis is None and n_bands != 1:
        raise ModelError(f"field {where}: a domain without a force axis has one band")


def _domain_fields(doc: JsonObject, where: str) -> tuple[
        JsonValue, tuple[str, ...], tuple[float, ...], float, JsonValue, str]:
    """(axis, columns, margins, axis margin, the bands as written, derived) of the
    file's domain, each there and of its type."""
    try:
        return (doc["axis"], tuple(doc["columns"]),
                tuple(float(v) for v in doc["margins"]), float(doc["axis_margin"]),
                doc["bands"], str(doc.get("derived", "training data")))
    except (KeyError, TypeError, ValueError) as exc:
        raise ModelError(f"field {where}: {exc!r} missing or not a number") from None


def _band_from_json(b: JsonValue, where: str, axis: object, k: int,
                    before: Band | None) -> Band:
    """One band as the file states it: its force range (none without a force axis),
    after the band `before` and not overlapping it, and `k` bounds lo <= hi."""
    try:
        a_lo, a_hi = ((-math.inf, math.inf) if axis is None and b["axis"] is None
                      else (float(v) for v in b["axis"]))
        lo = tuple(float(v) for v in b["lo"])
        hi = tuple(float(v) for v in b["hi"])
    except (KeyError, TypeError, ValueError):
        raise ModelError(f"field {where}: axis [lo, hi], lo and hi "
                         "expected") from None
    if len(lo) != k or len(hi) != k or not all(a <= c for a, c in zip(lo, hi, strict=True)):
        raise ModelError(f"field {where}: {k} bounds lo <= hi expected")
    if axis is not None and not (math.isfinite(a_lo) and a_lo <= a_hi
                                 and (before is None or a_lo >= before.axis_hi)):
        raise ModelError(f"field {where}.axis: bands in ascending force, "
                         "not overlapping")
    return Band(a_lo, a_hi, lo, hi)


def domain_of(model: InverseModel) -> Domain:
    """The model's domain: its file's (checked), else derived from what an older file
    holds (`Domain.derived` says which)."""
    inputs = [v.name for v in model.inputs]
    doc = model.provenance.get("domain")
    if doc is not None:
        return from_json(doc, inputs, model.output.name)
    cov = model.provenance.get("coverage")
    if isinstance(cov, dict):
        dom = from_coverage(cov, inputs, model.output.min, model.output.max)
        if dom is not None:
            return dom
    return from_ranges(model)


# -- the tick -----------------------------------------------------------------------------
class DomainTable:
    """`Domain` tabulated for the tick (see the module doc): `outside(force_n, a, b, y)`
    -> a bit mask, 0 inside.

    The arguments are the force, up to two other inputs (in the domain's column order;
    pass NaN for one the model lacks) and the model's output. Bit 0 is the force (beyond
    the bands), bit k + 1 the domain's k-th column; a NaN is never judged outside."""

    __slots__ = ("domain", "f0", "inv_df", "cells", "last", "n")

    def __init__(self, domain: Domain, cells: int = TABLE_CELLS) -> None:
        if len(domain.columns) > 3:
            raise ModelError(f"a domain of {len(domain.columns)} bounded columns: the tick "
                             "judges at most two inputs besides the force, and the output")
        self.domain = domain
        lo_f, hi_f = domain.axis_range
        self.n = len(domain.columns)
        if domain.axis is None or not hi_f > lo_f:
            got = domain.bounds_at(lo_f if math.isfinite(lo_f) else 0.0)
            assert got is not None
            self.f0, self.inv_df = -math.inf, 0.0
            self.cells: tuple[tuple[float, ...], ...] = (_padded(*got),)
            self.last = 0
            return
        df = (hi_f - lo_f) / cells
        self.f0, self.inv_df = lo_f, 1.0 / df
        edges = sorted({*(b.axis_lo for b in domain.bands), *(b.axis_hi for b in domain.bands)})
        table = []
        for c in range(cells):
            a, b = lo_f + c * df, lo_f + (c + 1) * df
            at = [a, min(b, hi_f), *(e for e in edges if a < e < b)]
            found = [bd for bd in (domain.bounds_at(x) for x in at) if bd is not None]
            lo = [min(bd[0][j] for bd in found) for j in range(self.n)]
            hi = [max(bd[1][j] for bd in found) for j in range(self.n)]
            table.append(_padded(lo, hi))
        self.cells = tuple(table)
        self.last = cells - 1

    def outside(self, force_n: float, a: float, b: float, y: float) -> int:
        """0 inside; else bit 0 the force, bits 1.. the columns (NaN: not judged)."""
        if self.inv_df:
            x = (force_n - self.f0) * self.inv_df
            if not 0.0 <= x <= self.last + 1:  # beyond the bands (NaN: not judged)
                return 1 if x == x else 0
            c = self.cells[int(x) if x < self.last else self.last]
        else:
            c = self.cells[0]
        mask = 0
        if a < c[0] or a > c[1]:
            mask = 2
        if b < c[2] or b > c[3]:
            mask |= 4
        if y < c[4] or y > c[5]:
            mask |= 8
        return mask

    def names(self, mask: int) -> list[str]:
        """The columns a mask names (the force first)."""
        d = self.domain
        cols = [d.axis or AXIS, *d.columns[:-1], *([""] * (2 - (self.n - 1))), d.columns[-1]]
        return [n for i, n in enumerate(cols) if n and mask & (1 << i)]


def _padded(lo: Sequence[float], hi: Sequence[float]) -> tuple[float, ...]:
    """(lo, hi) pairs of up to two inputs, then the output's; an input the model lacks
    is unbounded (its NaN argument compares false either way)."""
    pairs = [(lo[j], hi[j]) for j in range(len(lo) - 1)]
    pairs += [(-math.inf, math.inf)] * (2 - len(pairs))
    pairs.append((lo[-1], hi[-1]))
    return tuple(v for pair in pairs for v in pair)
