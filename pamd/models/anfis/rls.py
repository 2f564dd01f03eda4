"""Recursive least squares with exponential forgetting and a regularised covariance,
on a model linear in its parameters (an ANFIS model's rule consequents,
`CompiledAnfis.regressor`), allocation-free.

Role: one update from one sample (phi, y), with y = phi . theta the model's output:

    k     = P phi / (lambda + phi' P phi)
    theta = theta + k (y - phi' theta)
    P     = (P - k phi' P) / lambda

lambda < 1 forgets old samples (memory about 1 / (1 - lambda) updates), so the
estimate follows a truth that drifts. Where the samples do not excite the
parameters (a periodic trajectory excites a few of a model's 108 directions), P
would grow by 1 / lambda every update ("wind-up") and the next sample there would
move theta wildly; bounding P's trace instead (scaling the whole of P down) also
shrinks the gain where the samples do excite it, and the estimate then follows a
drift ever more slowly. So every update also adds the information
(1 - lambda) n / p0 on one coordinate, in turn (a rank-one Sherman-Morrison step
that leaves theta where it is): over n updates the information matrix gains
(1 - lambda) / p0 I per update, what forgetting takes from a prior p0 I, so P stays
near p0 I where nothing excites it and forgets as usual where the samples do
(regularised forgetting, Gunnarsson 1996). The trace is still never let past twice
its start (`trace_max`, a guard), and `reset()` puts P back to p0 I.

An update is computed into candidate buffers and only taken by `commit()`: the
caller checks the candidate (finite, within its bounds) first and the present
parameters stay as they were if it refuses it (`OutputBound`). Every buffer is
allocated once; an update is a dozen numpy calls on them (`out=` arguments), O(n^2)
for n parameters (108 for 27 rules of 3 inputs: about 55 us with the regularisation).

`OutputBound` measures a change of the consequents in bar of output: the largest
change of the model's output it makes at a grid of points over the training input
ranges (at most `GRID_MAX_POINTS`: 10 per input for 3 inputs, 31 for 2),
max |Phi_grid delta|, one (points x n) product (about 25 us for 1000 x 108). The
model's output is smooth between the points (Gaussian or bell memberships wider than
the grid's spacing), so this is what an operator means by "the adapted model differs
from the trained one by at most so many bar anywhere". The adaptation bounds
(`pamd.loop.control.adapt`) are stated in it.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from pamd.models.anfis.hybrid import _design, _with_ones

if TYPE_CHECKING:
    from pamd.models.anfis.model import AnfisModel

#: Most points of `OutputBound`'s grid (one (points x n) product per bound check).
GRID_MAX_POINTS = 1000


class Rls:
    """RLS with forgetting over `n` parameters, starting at `theta0` (see module doc)."""

    __slots__ = ("n", "theta", "P", "p0", "trace_max", "forgetting", "updates", "_cand_theta",
                 "_cand_P", "_Pphi", "_k", "_outer", "_step", "last_error", "_k_col",
                 "_col", "_col_row", "_reg",
                 "_Pphi_row")

    def __init__(self, theta0: np.ndarray, p0: float, forgetting: float,
                 trace_max: float | None = None) -> None:
        if not 0.0 < forgetting <= 1.0:
            raise ValueError(f"forgetting {forgetting!r}: must be in (0, 1]")
        if not p0 > 0.0:
            raise ValueError(f"p0 {p0!r}: must be > 0")
        n = int(theta0.size)
        self.n = n
        self.theta = np.array(theta0, dtype=np.float64)
        self.p0 = float(p0)
        self.trace_max = 2.0 * n * self.p0 if trace_max is None else float(trace_max)
        self.forgetting = float(forgetting)
        self.P = np.zeros((n, n))
        self._cand_theta = np.zeros(n)
        self._cand_P = np.zeros((n, n))
        self._Pphi = np.zeros(n)
        self._k = np.zeros(n)
        self._outer = np.zeros((n, n))
        self._col = np.zeros(n)
        self._reg = (1.0 - self.forgetting) * n / self.p0  # information per regularisation
        self._k_col = self._k[:, None]  # views for the outer products
        self._col_row = self._col[None, :]
        self._Pphi_row = self._Pphi[None, :]
        self._step = np.zeros(n)
        self.updates = 0
        self.last_error = math.nan
        self.reset()

    def reset(self) -> None:
        """The covariance back to p0 I (theta is kept)."""
        P = self.P
        P.fill(0.0)
        np.fill_diagonal(P, self.p0)

    def set_theta(self, theta: np.ndarray) -> None:
        np.copyto(self.theta, theta)

    @property
    def trace(self) -> float:
        return float(np.trace(self.P))

    def propose(self, phi: np.ndarray, y: float) -> np.ndarray | None:
        """The candidate parameters after the sample (phi, y), or None if the sample or
        the result is not finite (nothing changes). The present parameters stay until
        `commit`; the candidate's step is `step` (candidate - present)."""
        if not (math.isfinite(y) and np.isfinite(phi).all()):
            return None
        P, Pphi, k = self.P, self._Pphi, self._k
        lam = self.forgetting
        np.dot(P, phi, out=Pphi)
        den = lam + float(np.dot(phi, Pphi))
        if not (den > 0.0 and math.isfinite(den)):
            return None
        np.divide(Pphi, den, out=k)
        err = y - float(np.dot(phi, self.theta))
        self.last_error = err
        step = self._step
        np.multiply(k, err, out=step)
        theta = self._cand_theta
        np.add(self.theta, step, out=theta)
        cand = self._cand_P
        np.dot(self._k_col, self._Pphi_row, out=self._outer)  # k phi' P (P symmetric);
        # a (n x 1)(1 x n) product: BLAS, 2-3 x faster than np.outer's ufunc
        np.subtract(P, self._outer, out=cand)
        np.divide(cand, lam, out=cand)
        # regularisation: the information (1 - lambda) n / p0 on one coordinate, in turn
        # (Sherman-Morrison; theta does not move): P stays about p0 I where nothing
        # excites it (module doc)
        j = self.updates % self.n
        np.copyto(self._col, cand[:, j])
        c = self._reg / (1.0 + self._reg * float(self._col[j]))
        np.multiply(self._col, c, out=k)  # k's buffer: the step above is taken already
        np.dot(self._k_col, self._col_row, out=self._outer)
        np.subtract(cand, self._outer, out=cand)
        tr = float(np.trace(cand))
        if not (math.isfinite(tr) and np.isfinite(theta).all()):
            return None
        if tr > self.trace_max:  # wind-up: hold the trace at its bound
            np.multiply(cand, self.trace_max / tr, out=cand)
        return theta

    @property
    def step(self) -> np.ndarray:
        """The last candidate's step (candidate - present parameters)."""
        return self._step

    def scale_step(self, factor: float) -> None:
        """Shorten the candidate's step to `factor` of itself (a rate bound)."""
        np.multiply(self._step, factor, out=self._step)
        np.add(self.theta, self._step, out=self._cand_theta)

    def commit(self) -> None:
        """Take the candidate: swap the buffers (no copy)."""
        self.theta, self._cand_theta = self._cand_theta, self.theta
        self.P, self._cand_P = self._cand_P, self.P
        self.updates += 1
        if self.updates % 64 == 0:  # keep P symmetric against rounding
            np.add(self.P, self.P.T, out=self._outer)
            np.multiply(self._outer, 0.5, out=self.P)


class OutputBound:
    """The size of a consequent change in bar of output (see the module doc): the
    largest change it makes at a grid over the training input ranges. `phi_grid`
    holds the grid's regressors, one row per point (`CompiledAnfis.regressor` layout:
    the consequents column by column).

    `bar(delta)` measures any change. The adaptation's two bounds per update take one
    product, not two: `propose(step)` measures a step (keeping its change at the
    grid), `scale_step` follows a shortened step, `total_with_step()` is the size of
    the change since `clear()` plus the step (the change so far is kept at the grid,
    not recomputed), and `commit()` adds the step to it."""

    __slots__ = ("phi_grid", "_out", "_step", "_total")

    def __init__(self, phi_grid: np.ndarray) -> None:
        self.phi_grid = np.ascontiguousarray(phi_grid, dtype=np.float64)
        n_points = self.phi_grid.shape[0]
        self._out = np.zeros(n_points)
        self._step = np.zeros(n_points)  # the proposed step's change at the grid
        self._total = np.zeros(n_points)  # the committed change at the grid

    @classmethod
    def for_model(cls, model: AnfisModel) -> OutputBound:
        """The grid of an ANFIS model: as many points per input as keep the grid within
        `GRID_MAX_POINTS` (at least 3), evenly over each input's training range."""
        d = model.n_inputs
        per_input = max(3, int(GRID_MAX_POINTS ** (1.0 / d) + 1e-9))
        axes = [np.linspace(lo, hi, per_input) for lo, hi in zip(model.input_lo,
                                                                   model.input_hi,
                                                                   strict=True)]
        X = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, d)
        S = model.scale(X)
        # training's least-squares design matrix (rule by rule) in the evaluator's
        # layout (input by input)
        cols = model.n_consequent_columns  # d + 1, or 1 (q alone) if constant
        design = _design(model.firing_strengths(S), _with_ones(S)[:, -cols:])
        n_points, n_rules = X.shape[0], model.n_rules
        return cls(design.reshape(n_points, n_rules, cols).transpose(0, 2, 1)
                   .reshape(n_points, -1))

    def bar(self, delta: np.ndarray) -> float:
        """The largest output change (bar) the parameter change `delta` makes on the
        grid."""
        out = self._out
        np.dot(self.phi_grid, delta, out=out)
        np.abs(out, out=out)
        return float(out.max())

    def propose(self, step: np.ndarray) -> float:
        """The size of a proposed step (bar), kept for the calls below."""
        np.dot(self.phi_grid, step, out=self._step)
        np.abs(self._step, out=self._out)
        return float(self._out.max())

    def scale_step(self, factor: float) -> None:
        np.multiply(self._step, factor, out=self._step)

    def total_with_step(self) -> float:
        """The size (bar) of the committed change plus the proposed step."""
        out = self._out
        np.add(self._total, self._step, out=out)
        np.abs(out, out=out)
        return float(out.max())

    def commit(self) -> None:
        np.add(self._total, self._step, out=self._total)

    def clear(self) -> None:
        """Back to no change (the trained consequents)."""
        self._total.fill(0.0)
