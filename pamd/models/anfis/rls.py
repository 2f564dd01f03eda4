"""Recursive least squares with a forgetting factor on a model linear in its parameters
(an ANFIS model's rule consequents, `CompiledAnfis.regressor`), allocation-free.

Role: one update from one sample (phi, y), with y = phi . theta the model's output:

    k     = P phi / (lambda + phi' P phi)
    theta = theta + k (y - phi' theta)
    P     = (P - k phi' P) / lambda

lambda < 1 forgets old samples (memory about 1 / (1 - lambda) updates), so the
estimate follows a truth that drifts. Without excitation, P grows by 1 / lambda each
update ("wind-up") and the next sample would move theta a lot: its trace is held at
or below `trace_max` (the whole of P scaled down). `reset()` puts P back to its
initial p0 I.

An update is computed into candidate buffers and only taken by `commit()`: the
caller checks the candidate (finite, within its bounds) first and the present
parameters stay as they were if it refuses it (`OutputBound`). Every buffer is
allocated once; an update is a dozen numpy calls on them (`out=` arguments), O(n^2)
for n parameters (108 for 27 rules of 3 inputs: about 20 us).

`OutputBound` measures a change of the consequents in bar of output: the largest
change of the model's output it can make anywhere in the training input ranges,
max_r (|dq_r| + sum_i |dp_ri| max|s_i|), with s_i the scaled inputs over their
ranges (the output is a convex mix of the rules' linear functions, so no input in
range can move the output more). The adaptation bounds (`pamd.control.adapt`) are
stated in it.
"""

from __future__ import annotations

import math

import numpy as np


class Rls:
    """RLS with forgetting over `n` parameters, starting at `theta0` (see module doc)."""

    __slots__ = ("n", "theta", "P", "p0", "trace_max", "forgetting", "updates", "_cand_theta",
                 "_cand_P", "_Pphi", "_k", "_outer", "_step", "last_error", "_k_col",
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
        self.trace_max = n * self.p0 if trace_max is None else float(trace_max)
        self.forgetting = float(forgetting)
        self.P = np.zeros((n, n))
        self._cand_theta = np.zeros(n)
        self._cand_P = np.zeros((n, n))
        self._Pphi = np.zeros(n)
        self._k = np.zeros(n)
        self._outer = np.zeros((n, n))
        self._k_col = self._k[:, None]  # views for the outer product
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
    """The size of a consequent change in bar of output (see the module doc).

    `weights` holds max|s_i| over the training range per input, then 1 (the constant);
    parameters are laid out column by column (`CompiledAnfis.theta`)."""

    __slots__ = ("weights", "n_rules", "_abs", "_rows")

    def __init__(self, max_abs_scaled: np.ndarray, n_rules: int) -> None:
        self.weights = np.concatenate([np.asarray(max_abs_scaled, dtype=np.float64), [1.0]])
        self.n_rules = n_rules
        self._abs = np.zeros((self.weights.size, n_rules))
        self._rows = np.zeros(n_rules)

    @classmethod
    def for_model(cls, lo: np.ndarray, hi: np.ndarray, offset: np.ndarray, span: np.ndarray,
                  n_rules: int) -> OutputBound:
        """From the training input ranges and the scaling of an ANFIS model."""
        s_lo = np.abs((np.asarray(lo) - offset) / span)
        s_hi = np.abs((np.asarray(hi) - offset) / span)
        return cls(np.maximum(s_lo, s_hi), n_rules)

    def bar(self, delta: np.ndarray) -> float:
        """The largest output change (bar) the parameter change `delta` can make."""
        a = self._abs
        np.abs(delta.reshape(a.shape), out=a)
        np.dot(self.weights, a, out=self._rows)
        return float(self._rows.max())
