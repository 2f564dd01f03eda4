"""Seed 003's analytic QUPI inverse (eqs. 8-11): the simplified QUPI, pressure ->
displacement, and its inverse in closed form, displacement -> pressure, as the
feedforward of kind ``fn-qupi``.

The paper simplifies the QUPI model for its inverse to (eq. 8)

    Gamma[w](k) = q w(k) + sum_j d_j F_rj[w](k)

(q > 0 and every q + sum_{i<=j} d_i > 0; F_r the play operator
z(k) = max(w - r, min(w + r, z(k - 1)))), whose inverse is again such a model (eqs.
9-11, the Prandtl-Ishlinskii inversion):

    Gamma^-1[y] = (1/q) y + sum_j g_j F_rbar_j[y]
    rbar_j = q r_j + sum_{i<j} d_i (r_j - r_i)
    g_j = -d_j / ((q + sum_{i<=j} d_i) (q + sum_{i<j} d_i))

(the paper's garbled eq. 11 printed without the minus sign and the product; this is
the inversion it cites). The quadratic part of QUPI enters through the input: w is a
quadratic map of the pressure, w = phi(p) = (p - p0) + beta (p - p0)^2 (monotone on
[p0, pm]), so each operator's edges are parabolas in p (QUPI's envelopes, with one
shape for all operators), and phi^-1 is closed-form too. The output is y = Gamma[w] +
c (c: the displacement at p0 from rest). Identification: for each beta on a grid the weights by
least squares, kept if they satisfy the invertibility condition above (the slope of
every branch, q + sum_{i<=j} d_i, positive), else by non-negative least squares (d_j
>= 0 satisfies it); the paper identifies q^-1 and g by PSO on the same least-squares
fitness. The beta of the least training error is kept.
Thresholds r_j evenly over (0, 0.8 of the input range], n = 10 (the paper's).

The inverse composed with the forward model is the identity (to rounding) wherever
both start from matching states: every operator starts relaxed (z = 0 at w = 0, y =
0) and `reset` puts both on the ascending branch from there (the rig comes up from
rest, as `pamd.models.qupi` does).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

from pamd.models.document import mapping, numbers
from pamd.wire.declare.jsonsafe import JsonObject
from pamd.wire.errors import ModelError

DEFAULT_OPERATORS = 10  # n (seed 003, "Set n = 10")
THRESHOLD_SPAN = 0.8
#: beta (p - p0) tried: phi stays monotone (slope 1 + 2 beta (p - p0) > 0) on [p0, pm]
BETA_GRID = (-0.45, -0.4, -0.3, -0.2, -0.1, 0.0, 0.2, 0.5, 1.0, 2.0, 4.0)
#: q's least value, as a share of the displacement range over the input range
Q_FLOOR = 1e-3


def play(w: np.ndarray, r: np.ndarray, z0: np.ndarray) -> np.ndarray:
    """Play operators of thresholds r (m,) along w (n,) from states z0: (n x m)."""
    out = np.empty((w.size, r.size))
    z = z0.copy()
    for k in range(w.size):
        z = np.maximum(w[k] - r, np.minimum(w[k] + r, z))
        out[k] = z
    return out


def pi_inverse(q: float, r: np.ndarray, d: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
    """(1/q, rbar, g) of the inverse of q w + sum d_j F_rj[w] (r ascending, module doc)."""
    cum = np.concatenate([[0.0], np.cumsum(d)])  # sum_{i<j} d_i at index j
    rbar = np.array([q * r[j] + float(np.sum(d[:j] * (r[j] - r[:j]))) for j in range(r.size)])
    g = -d / ((q + cum[1:]) * (q + cum[:-1]))
    return 1.0 / q, rbar, g


class PlayQupi:
    """The simplified QUPI y = q phi(p) + sum d_j F_rj[phi(p)] + c and its inverse."""

    def __init__(self, p0: float, pm: float, beta: float, r: ArrayLike, d: ArrayLike, q: float,
                 c: float) -> None:
        self.p0, self.pm, self.beta = float(p0), float(pm), float(beta)
        self.r = np.array(r, dtype=np.float64)
        self.d = np.array(d, dtype=np.float64)
        self.q, self.c = float(q), float(c)
        if not self.pm > self.p0:
            raise ModelError("fn-qupi inverse: empty pressure range")
        if not 1.0 + 2.0 * self.beta * (self.pm - self.p0) > 0.0:
            raise ModelError("fn-qupi inverse: the quadratic input map is not monotone")
        if self.r.shape != self.d.shape or np.any(np.diff(self.r) <= 0) or np.any(self.r < 0):
            raise ModelError("fn-qupi inverse: thresholds must ascend from >= 0, one weight "
                             "each")
        if not (self.q > 0 and np.all(self.q + np.cumsum(self.d) > 0)):
            raise ModelError("fn-qupi inverse: q and every q + d_1 + ... + d_j must be > 0 "
                             "(else the model has no inverse)")
        if not all(np.all(np.isfinite(v)) for v in (self.r, self.d, [self.q, self.c, beta])):
            raise ModelError("fn-qupi inverse: non-finite parameters")
        self.q_inv, self.rbar, self.g = pi_inverse(self.q, self.r, self.d)

    # -- the maps -------------------------------------------------------------------------
    def phi(self, p: np.ndarray) -> np.ndarray:
        x = np.clip(p, self.p0, self.pm) - self.p0
        mapped: np.ndarray = x + self.beta * x * x
        return mapped

    def phi_inv(self, w: np.ndarray) -> np.ndarray:
        b, w_hi = self.beta, float(self.phi(np.array([self.pm]))[0])
        w = np.clip(w, 0.0, w_hi)
        if b == 0.0:
            return self.p0 + w
        return self.p0 + 2.0 * w / (1.0 + np.sqrt(np.maximum(1.0 + 4.0 * b * w, 0.0)))

    def forward(self, p: np.ndarray) -> np.ndarray:
        """Displacement along a pressure sequence, from a reset at its first value."""
        w = self.phi(np.asarray(p, dtype=np.float64))
        z = play(w, self.r, np.maximum(w[0] - self.r, 0.0))
        return self.q * w + z @ self.d + self.c

    def inverse(self, u: np.ndarray) -> np.ndarray:
        """Pressure along a displacement sequence, from a reset at its first value (the
        closed-form inverse; the caller holds u to the identified range)."""
        y = np.asarray(u, dtype=np.float64) - self.c
        z = play(y, self.rbar, np.maximum(y[0] - self.rbar, 0.0))
        return self.phi_inv(self.q_inv * y + z @ self.g)

    @property
    def n_params(self) -> int:
        return int(self.d.size + 3)  # d, q, c, beta

    def as_dict(self) -> JsonObject:
        return {"p_range": [self.p0, self.pm], "beta": self.beta, "r": self.r.tolist(),
                "d": self.d.tolist(), "q": self.q, "c": self.c}

    @classmethod
    def from_doc(cls, doc: object, where: str) -> PlayQupi:
        doc = mapping(doc, where)
        p0, pm = numbers(doc, "p_range", where, 2)
        r, d = numbers(doc, "r", where), numbers(doc, "d", where)
        beta, q, c = (numbers({"v": [doc.get(k)]}, "v", f"{where}.{k}", 1)[0]
                      for k in ("beta", "q", "c"))
        return cls(p0, pm, beta, r, d, q, c)


def fit_play_qupi(p_runs: list[np.ndarray], u_runs: list[np.ndarray],
                  use_runs: list[np.ndarray], n_ops: int = DEFAULT_OPERATORS) -> PlayQupi:
    """The simplified QUPI of displacement u on pressure p (module doc), the operators run
    over whole runs, the rows of `use_runs` fitted."""
    from scipy.optimize import nnls  # heavy: only training needs it

    p_all, u_all = np.concatenate(p_runs), np.concatenate(u_runs)
    use = np.concatenate(use_runs)
    p0, pm = float(p_all.min()), float(p_all.max())
    if not (pm > p0 and np.ptp(u_all) > 0):
        raise ModelError("fn-qupi: the data do not span a range of pressure and length")
    best: tuple[float, PlayQupi] | None = None
    for bx in BETA_GRID:
        beta = bx / (pm - p0)
        shape = PlayQupi(p0, pm, beta, [1.0], [0.0], 1.0, 0.0)
        w_runs = [shape.phi(p) for p in p_runs]
        w_hi = float(shape.phi(np.array([pm]))[0])
        r = THRESHOLD_SPAN * w_hi * np.arange(1, n_ops + 1) / n_ops
        w_all = np.concatenate(w_runs)
        Z = np.vstack([play(w, r, np.maximum(w[0] - r, 0.0)) for w in w_runs])
        q_min = Q_FLOOR * float(np.ptp(u_all)) / w_hi
        A = np.column_stack([w_all, Z, np.ones(w_all.size)])[use]
        theta = np.linalg.lstsq(A, u_all[use], rcond=None)[0]
        q, d, c = float(theta[0]), theta[1:-1], float(theta[-1])
        if not (q > q_min and np.all(q + np.cumsum(d) > q_min)):
            # u - q_min w = (q - q_min) w + Z d + c+ - c-, every coefficient >= 0
            B = np.column_stack([A, -np.ones(A.shape[0])])
            th, _ = nnls(B, u_all[use] - q_min * w_all[use], maxiter=50 * B.shape[1])
            q, d, c = q_min + float(th[0]), th[1:-2], float(th[-2] - th[-1])
        model = PlayQupi(p0, pm, beta, r, d, q, c)
        sse = float(np.sum((A @ np.concatenate([[q], d, [c]]) - u_all[use]) ** 2))
        if best is None or sse < best[0]:
            best = (sse, model)
    assert best is not None
    return best[1]


class CompiledInverse:
    """The closed-form inverse for the tick: displacement -> pressure, n play operators
    updated in place, one square root (the caller holds u to the identified range; the
    pressure is held to [p0, pm])."""

    __slots__ = ("evaluate", "reset")

    def __init__(self, m: PlayQupi) -> None:
        rbar, g = tuple(m.rbar.tolist()), tuple(m.g.tolist())
        n = len(rbar)
        q_inv, c = m.q_inv, m.c
        p0, beta = m.p0, m.beta
        w_hi = float(m.phi(np.array([m.pm]))[0])
        state = [0.0] * n

        def evaluate(u: float) -> float:
            y = u - c
            w = q_inv * y
            for j in range(n):
                z = state[j]
                lo, hi = y - rbar[j], y + rbar[j]
                if z < lo:
                    z = lo
                elif z > hi:
                    z = hi
                state[j] = z
                w += g[j] * z
            if w < 0.0:
                w = 0.0
            elif w > w_hi:
                w = w_hi
            if beta == 0.0:
                return p0 + w
            return p0 + 2.0 * w / (1.0 + math.sqrt(max(1.0 + 4.0 * beta * w, 0.0)))

        def reset(u: float) -> None:
            y = u - c
            for j in range(n):
                state[j] = max(y - rbar[j], 0.0)

        self.evaluate = evaluate
        self.reset = reset
        reset(c)
